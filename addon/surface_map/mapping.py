"""Compatibility only: the module names before the add-on was split by what each file does
(docs/addon.md). New code imports geometry, distortion, colours, uv_transfer, landmarks,
morph or side directly."""
from .geometry import *  # noqa: F401,F403
from .distortion import *  # noqa: F401,F403
from .colours import *  # noqa: F401,F403
from .uv_transfer import *  # noqa: F401,F403
from .landmarks import *  # noqa: F401,F403
from .morph import *  # noqa: F401,F403
from .side import fingerprint  # noqa: F401
