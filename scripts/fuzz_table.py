"""Print the fuzzing table of docs/reliability.md: inputs per reader, read, refused, tracebacks, signals,
hangs (tests/fuzz/harness.py: seeded byte mutations, each reader in child processes).

    python scripts/fuzz_table.py --inputs 100000          # the documented run (>= 10^5 per reader)
    python scripts/fuzz_table.py --inputs 2000 --readers plots.csv config.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository: tests.fuzz.harness

from tests.fuzz.harness import fuzz, readers  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", type=int, default=100_000, help="inputs per reader (default 100 000)")
    ap.add_argument("--seed", type=int, default=28)
    ap.add_argument("--readers", nargs="*", default=None, help="a subset of the readers (default: all)")
    args = ap.parse_args()
    names = args.readers or readers()
    print("| reader | inputs | read | refused | tracebacks | signals | hangs | seconds |")
    print("|---|---|---|---|---|---|---|---|")
    bad = 0
    for name in names:
        t0 = time.perf_counter()
        tally, seen = fuzz(name, args.inputs, args.seed)
        bad += tally["traceback"] + tally["signal"] + tally["hang"]
        print(f"| {name} | {sum(tally.values()):,} | {tally['read']:,} | {tally['refused']:,} | {tally['traceback']} | "
              f"{tally['signal']} | {tally['hang']} | {time.perf_counter() - t0:.0f} |", flush=True)
        for s in seen:
            print(f"    {name}: {s}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
