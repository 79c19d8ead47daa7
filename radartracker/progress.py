"""Progress bars on stderr for the long steps of a command (reading, writing, figures).

``radartracker --quiet`` (and a command's own ``--quiet``) sets ``TQDM_DISABLE``; tqdm itself reads its
``TQDM_*`` settings once, when it is imported, so a process that imported tqdm before (a test, an
application calling :func:`radartracker.cli.main` more than once) would not see it: :func:`progress_bar`
reads it when the bar is made.
"""

from __future__ import annotations

import os
from typing import Any

from tqdm import tqdm


def progress_bar(iterable: Any = None, **kwargs: Any) -> tqdm:
    """A tqdm bar that appears once its work has taken 2 s (``delay``) and redraws at most once a second
    (``mininterval``), off while ``TQDM_DISABLE`` is set (or with ``disable=True``)."""
    off = bool(kwargs.pop("disable", False)) or os.environ.get("TQDM_DISABLE", "") not in ("", "0")
    return tqdm(iterable, **{"delay": 2.0, "mininterval": 1.0, **kwargs}, disable=off)
