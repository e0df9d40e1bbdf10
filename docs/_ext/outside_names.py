"""Type names from outside the documented package (``numpy.ndarray``, ``str``,
``typing.Any``, ...) left as the plain text Sphinx leaves them, without its search.

The signatures and parameter lists carry some 8,500 references of the "fuzzy" kind (a
type in a docstring or an annotation), mostly to names the site does not document.
Sphinx's Python domain tries each one against every documented object
(``name.endswith("." + target)``), so the build spent about a seventh of its time on
these lookups that find nothing. This transform runs just before Sphinx's own reference
resolution and settles, for such a reference, only the case in which that search can
find nothing — no documented object is named ``target``, ``module.target`` or
``module.Class.target``, and none ends in ``"." + target`` (one set of dotted name
suffixes answers that) — exactly as Sphinx settles it: the ``missing-reference`` event,
then the reference's own text in its place. Every other reference goes on to Sphinx.
"""

from __future__ import annotations

from docutils import nodes
from sphinx import addnodes
from sphinx.errors import NoUri
from sphinx.transforms.post_transforms import ReferencesResolver, SphinxPostTransform


def dotted_suffixes(names) -> frozenset[str]:
    """Every ending of every dotted name that starts after one of its dots:
    ``"a.b.c"`` gives ``"b.c"`` and ``"c"``."""
    found = set()
    for name in names:
        start = name.find(".")
        while start != -1:
            found.add(name[start + 1:])
            start = name.find(".", start + 1)
    return frozenset(found)


class OutsideNames(SphinxPostTransform):
    """Settle the fuzzy Python references that name no documented object (module docstring)."""

    default_priority = ReferencesResolver.default_priority - 1

    def run(self, **kwargs) -> None:
        if self.config.nitpicky:  # Sphinx then warns about each: leave them to it
            return
        domain = self.env.get_domain("py")
        objects = domain.objects
        suffixes = None
        for node in list(self.document.findall(addnodes.pending_xref)):
            if node.get("refdomain") != "py" or not node.get("refspecific") or node.get("refwarn") or not node.children:
                continue
            if suffixes is None:
                suffixes = dotted_suffixes(objects)
            if self.names_nothing(node, objects, suffixes):
                contnode = node[0].deepcopy()
                found = self.app.emit_firstresult("missing-reference", self.env, node, contnode,
                                                  allowed_exceptions=(NoUri,))
                node.replace_self(found or contnode)

    @staticmethod
    def names_nothing(node: nodes.Element, objects, suffixes: frozenset[str]) -> bool:
        """Whether the domain's search (``find_obj`` with ``searchmode=1``) cannot match
        ``node``'s target, whatever the object types its role allows."""
        name = node["reftarget"].removesuffix("()")
        module, cls = node.get("py:module"), node.get("py:class")
        candidates = [name, f"{module}.{name}" if module else None, f"{module}.{cls}.{name}" if module and cls else None]
        return bool(name) and not any(c in objects for c in candidates if c) and name not in suffixes


def setup(app):  # pragma: no cover - exercised by the docs build
    app.add_post_transform(OutsideNames)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
