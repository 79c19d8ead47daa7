"""Robust stream clock of an input stream: a single far-off time stamp is rejected, never the good inputs after it.

The stream time T is the median of the last ``window`` admitted time stamps of the stream (all its
sources together). An input at time t is *ahead* when t > T + ``max_ahead_s``; it is rejected and
counted, and — being rejected — never moves T, so the inputs after it are judged against the good
ones. A genuine jump of the whole stream (a recording that resumes after a pause) shows as a run of
``step_after`` consecutive inputs all ahead of T and within ``max_ahead_s`` of each other: the last
of them is admitted and the run becomes the new clock (the ``step_after − 1`` before it were
rejected — the price of not trusting one time stamp).

Inputs *behind* T are not this rule's business: the reader's per-radar ordering check and the
TrackManager's reordering horizon judge them, and both compare with *admitted* inputs only.

Why one clock per stream rather than per source: a source whose own clock is wrong (a radar 30
min ahead) would establish its own time after ``step_after`` inputs and then drag the stream; with
one stream clock its inputs keep being rejected while the other sources' good inputs interleave,
and a radar that was silent for a while is judged against the others' time, not its own stale one.
The same rule (this class) runs in the scenario reader, the labelled replay and
:meth:`radartracker.tracking.manager.TrackManager.process`. Defaults: docs/reliability.md.
"""

from __future__ import annotations

import math
import statistics
from collections import deque

import attrs


@attrs.frozen
class ClockConfig:
    """``max_ahead_s``: how far ahead of the stream time an input may be; ``window``: admitted time
    stamps the median is taken over; ``step_after``: consecutive consistent inputs ahead that make a
    clock step."""

    max_ahead_s: float = attrs.field(default=300.0, validator=attrs.validators.gt(0.0))
    window: int = attrs.field(default=9, validator=attrs.validators.ge(1))
    step_after: int = attrs.field(default=3, validator=attrs.validators.ge(1))


class StreamClock:
    """Admit or reject time stamps of one stream (see the module docstring for the rule)."""

    def __init__(self, config: ClockConfig | None = None) -> None:
        self.config = config or ClockConfig()
        self._recent: deque[float] = deque(maxlen=self.config.window)
        self._run: list[float] = []
        self._low = -math.inf  # at most the least time of the window, so at most T (−∞: not known)
        self.steps = 0  # clock steps so far

    @property
    def now(self) -> float:
        """The robust stream time T (−∞ before the first input)."""
        return statistics.median_low(self._recent) if self._recent else -math.inf

    def admit(self, t: float) -> bool:
        """True if ``t`` is admitted (and becomes part of the clock); False if it is too far ahead."""
        if not math.isfinite(t):
            return False
        ahead = self.config.max_ahead_s
        # t <= _low + ahead <= T + ahead admits most inputs at the cost of one comparison
        if t > self._low + ahead and self._recent:  # not settled: the bound made the window's least time,
            self._low = min(self._recent)  # then T itself
            if t > self._low + ahead and t > self.now + ahead:
                return self._ahead(t)
        self._recent.append(t)
        if t < self._low:
            self._low = t
        if self._run:
            self._run = []
        return True

    def _ahead(self, t: float) -> bool:
        """``t`` is ahead of the stream time: rejected, unless it completes a run that steps the clock."""
        if self._run and abs(t - self._run[0]) > self.config.max_ahead_s:
            self._run = []
        self._run.append(t)
        if len(self._run) < self.config.step_after:
            return False
        self._recent.clear()
        self._recent.extend(self._run)
        self._low = min(self._run)
        self._run = []
        self.steps += 1
        return True

    @property
    def run_length(self) -> int:
        """How many consecutive consistent inputs ahead of the stream time have been seen (a clock step
        needs ``step_after``)."""
        return len(self._run)

    def state_dict(self) -> dict:
        """The clock's state as plain values (for TrackManager snapshots)."""
        return {"recent": list(self._recent), "run": list(self._run)}

    def load_state_dict(self, state: dict) -> None:
        self._recent = deque((float(t) for t in state["recent"]), maxlen=self.config.window)
        self._run = [float(t) for t in state["run"]]
        self._low = -math.inf
