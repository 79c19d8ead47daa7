"""Names, defaults and the number check of the command line's settings, with no heavy import.

The command line builds every sub-command's parser to print ``radartracker --help``: what a parser
needs (the choices and defaults it shows) lives here, apart from the modules that use the settings
(:mod:`radartracker.pipeline.config`, :mod:`radartracker.simulation.scenarios`), which import numpy,
numba and the tracker.
"""

from __future__ import annotations

import math
from typing import Any

from radartracker.errors import ConfigurationError

DEFAULT_Q = 5.0  # m²/s³: real aircraft turn; with the seed's q = 0 a manoeuvre is explained away as bias
ASSOCIATIONS = ("auto", "labels", "manager")
ARCHITECTURES = ("central", "distributed")
# the built-in scenarios of radartracker.simulation.scenarios.STANDARD_SCENARIOS (a test keeps them equal)
SCENARIOS = ("demo", "manoeuvres", "paris", "seed", "tracking")


def check_number(option: str, value: Any, *, lo: float | None = None, lo_open: bool = False,
                 hi: float | None = None, integer: bool = False) -> float | int:
    """``value`` as a finite number within bounds, or a ConfigurationError naming ``option``."""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ConfigurationError(f"{option}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise ConfigurationError(f"{option}: {value!r} is not finite")
    if integer and number != int(number):
        raise ConfigurationError(f"{option}: {value!r} is not an integer")
    if lo is not None and (number <= lo if lo_open else number < lo):
        raise ConfigurationError(f"{option}: {value!r} must be {'>' if lo_open else '>='} {lo}")
    if hi is not None and number > hi:
        raise ConfigurationError(f"{option}: {value!r} must be <= {hi}")
    return int(number) if integer else number
