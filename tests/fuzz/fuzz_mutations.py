"""Hypothesis strategies that break scenario, sweep, plan and pattern files.

A mutation picks a place in the parsed file (any mapping key or list element, the top
level included) and does one thing to it: replaces the value with an adversarial one
(NaN, ±inf, huge or negative numbers, numbers as strings, wrong types, nesting,
long strings), rescales a number, deletes it, renames its key, adds an unknown key,
empties, repeats or wraps a list. One to three mutations are applied in turn, so a
mutant can be wrong in several places at once.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from hypothesis import strategies as st

SPECIAL_NUMBERS = (math.nan, math.inf, -math.inf, 1e308, -1e308, 1e12, 2e9, 1e9 + 1, 1e-300, -1e-9, 0, -1, 2**31,
                   2**63, 2**64, 10**12, -(10**15), 10**40)
SPECIAL_TEXT = ("nan", "NaN", ".inf", "-inf", "1e400", "1e308", "", " ", "abc", "yes", "null", "~", "0x10", "1_000",
                "10" * 40, "é\u202e", "\x00")

numbers = st.one_of(st.sampled_from(SPECIAL_NUMBERS), st.floats(allow_nan=True, allow_infinity=True),
                    st.integers(min_value=-(2**70), max_value=2**70))
text = st.one_of(st.sampled_from(SPECIAL_TEXT), st.text(max_size=10), st.just("x" * 20_000))
scalars = st.one_of(numbers, text, st.booleans(), st.none())
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                      max_leaves=6)
values = st.one_of(values, st.builds(lambda depth: nested(depth), st.integers(10, 200)))


def nested(depth: int) -> Any:
    """``[[[...[1]...]]]`` ``depth`` levels deep."""
    value: Any = 1
    for _ in range(depth):
        value = [value]
    return value


def places(node: Any, path: tuple = ()) -> list[tuple]:
    """Every path into ``node`` (the top level is ``()``), in document order."""
    out = [path]
    if isinstance(node, dict):
        for key, value in node.items():
            out += places(value, (*path, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            out += places(value, (*path, index))
    return out


def at(node: Any, path: tuple) -> Any:
    for key in path:
        node = node[key]
    return node


def rescaled(value: Any, factor: float) -> Any:
    """A number times ``factor`` (an integer stays an integer when it can), else the value."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return value
    if isinstance(value, int) and float(factor).is_integer():
        return value * int(factor)
    return value * factor


OPERATIONS = ("replace", "replace", "replace", "rescale", "as_text", "delete", "rename", "unknown_key", "empty",
              "repeat", "wrap")


def rotated(items: list, offset: int) -> list:
    """``items`` rotated by ``offset``: equal draws pick different items for different files."""
    k = offset % len(items)
    return items[k:] + items[:k]


@st.composite
def mutated(draw: st.DrawFn, original: dict, *, offset: int = 0, repeat_limit: int = 50) -> tuple[object, list[str]]:
    """``(mutant, what was done)``: one to three mutations of ``original``; ``offset`` (a
    per-file number) rotates the choices, so that derandomized runs of the same draws
    mutate different places of different files."""
    mapping: object = copy.deepcopy(original)
    done = []
    for step in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(rotated(places(mapping), offset + 7 * step)))
        operation = draw(st.sampled_from(rotated(list(OPERATIONS), offset + step)))
        mapping, note = apply(draw, mapping, path, operation, repeat_limit)
        done.append(note)
    return mapping, done


GARBLES = (b"\t", b"\x00", b"\xff\xfe", b"\xe9", b": ", b"- ", b"&a ", b"*a ", b"*b", b"!!python/object:os.system ",
           b"!!binary ", b"[", b"]", b"{", b"}", b"\n  ", b"\n", b"#", b"'", b'"', b"? ", b"---\n", b"<<: *a\n", b"1" * 5000)


@st.composite
def garbled(draw: st.DrawFn, original: bytes) -> tuple[bytes, list[str]]:
    """The file's bytes, cut short, with bytes inserted or lines deleted or repeated."""
    data = original
    done = []
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(data)))
        operation = draw(st.sampled_from(["insert", "insert", "cut", "delete_line", "repeat_line", "binary"]))
        lines = data.split(b"\n")
        j = draw(st.integers(0, len(lines) - 1))
        if operation == "insert":
            data = data[:i] + draw(st.sampled_from(GARBLES)) + data[i:]
        elif operation == "cut":
            data = data[:i]
        elif operation == "delete_line":
            data = b"\n".join(lines[:j] + lines[j + 1:])
        elif operation == "repeat_line":
            data = b"\n".join(lines[: j + 1] + lines[j:])
        else:
            data = data[:i] + draw(st.binary(max_size=40)) + data[i:]
        done.append(f"{operation} at {i}")
    return data, done


def apply(draw: st.DrawFn, mapping: Any, path: tuple, operation: str, repeat_limit: int) -> tuple[Any, str]:
    where = ".".join(map(str, path)) or "<top>"
    node = at(mapping, path)
    parent, key = (at(mapping, path[:-1]), path[-1]) if path else (None, None)

    def put(value: Any) -> Any:
        if parent is None:  # the top level itself: a file holding a list, a number...
            return value
        parent[key] = value
        return mapping

    if operation == "unknown_key" and isinstance(node, dict):
        node[draw(st.sampled_from(["bogus", "Name", "max_step", "robot", "seeds_", "1"]))] = draw(values)
        return mapping, f"unknown key in {where}"
    if operation == "delete" and parent is not None:
        del parent[key]
        return mapping, f"delete {where}"
    if operation == "rename" and isinstance(parent, dict):
        parent[str(key)[:-1] + str(key)[-1:] * 2] = parent.pop(key)
        return mapping, f"rename {where}"
    if operation == "rescale":
        factor = draw(st.sampled_from([-1, 0, 1e-12, 1e-3, 1000, 1e6, 1e12, 2**40]))
        return put(rescaled(node, factor)), f"{where} × {factor}"
    if operation == "as_text":
        return put(str(node)), f"{where} as text"
    if operation == "empty":
        return put(type(node)() if isinstance(node, (list, dict)) else ""), f"empty {where}"
    if operation == "repeat" and isinstance(node, list) and node:
        return put(node * draw(st.integers(2, repeat_limit))), f"repeat {where}"
    if operation == "wrap":
        return put([node]), f"wrap {where}"
    value = draw(values)
    return put(value), f"{where} = {str(value)[:40]!r}"
