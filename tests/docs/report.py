"""What the docs test checked, counted across its tests and printed at the end of the run (conftest.py)."""

from __future__ import annotations

from collections import Counter


class Report:
    def __init__(self) -> None:
        self.counts: Counter = Counter()
        self.slow: list[str] = []
        self.skipped: list[str] = []

    def add(self, what: str, n: int) -> None:
        self.counts[what] += n

    def tally(self, tally) -> None:
        self.add("blocks run", len(tally.run))
        self.add("commands run", tally.commands)
        self.add("commands assumed", tally.assumed)
        self.slow += tally.slow
        self.skipped += tally.skipped

    def lines(self) -> list[str]:
        if not self.counts:
            return []
        out = ["docs: " + ", ".join(f"{k} {v}" for k, v in self.counts.items())]
        out += [f"docs: slow (run with -m slow): {w}" for w in self.slow]
        out += [f"docs: skipped: {w}" for w in self.skipped]
        return out


REPORT = Report()
