"""Suite-wide test settings.

Under CI (``CI=true``) hypothesis runs derandomized, so a green run is reproducible; on a
developer's machine it keeps exploring new examples each run (and remembers failures).
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
    settings.load_profile("ci")
