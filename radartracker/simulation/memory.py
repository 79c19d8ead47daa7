"""Whether a generator's output can fit in memory, decided before it starts.

A simulation holds its whole scenario (plots, ADS-B reports, truth) in memory until it is written,
so a size that cannot fit is refused up front with a message saying so, instead of running for
minutes and then being killed. The estimate is linear in what grows:

    bytes ≈ aircraft × (A + B × duration_s)

with A = 2 kB per aircraft (its legs and identity) and B = 160 B per aircraft-second (its plots,
ADS-B reports and truth rows, and the arrays they pass through), measured with
``/usr/bin/time -f %M`` on ``simulate --scenario traffic`` (28 radars): 2 000 and 8 000 aircraft
for 180 s, 2 000 for 720 s — 310, 493 and 483 MB peak RSS, about 250 MB of it the interpreter and
libraries. The estimate is doubled (the margin of a measurement on three sizes) and compared with
the memory the process may still use: the system's available memory, or what is left under the
process's address-space limit (``ulimit -v``) if that is smaller.
"""

from __future__ import annotations

import math
import resource
from pathlib import Path

from radartracker.errors import ConfigurationError

PER_AIRCRAFT_B = 2_000.0
PER_AIRCRAFT_SECOND_B = 160.0
MARGIN = 2.0


def traffic_bytes(aircraft: int, duration_s: float) -> float:
    """The estimated peak memory (bytes) of a traffic simulation, margin included (module docstring)."""
    return MARGIN * aircraft * (PER_AIRCRAFT_B + PER_AIRCRAFT_SECOND_B * duration_s)


def _meminfo(key: str) -> float:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith(key + ":"):
                return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return math.inf  # not Linux: no estimate of the machine's memory, only the process limit


def _vm_size() -> float:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return 0.0


def available_bytes() -> float:
    """The memory this process may still use: MemAvailable, or what its RLIMIT_AS leaves if smaller."""
    limit, _ = resource.getrlimit(resource.RLIMIT_AS)
    left = math.inf if limit == resource.RLIM_INFINITY else limit - _vm_size()
    return min(_meminfo("MemAvailable"), left)


def check_fits(what: str, needed: float) -> None:
    """A ConfigurationError saying ``what`` needs ``needed`` bytes when less memory is available."""
    have = available_bytes()
    if needed > have:
        raise ConfigurationError(f"{what} needs about {needed / 2**30:.1f} GiB of memory; {max(have, 0) / 2**30:.1f} "
                                 "GiB available: refused (choose fewer aircraft or a shorter duration)")
