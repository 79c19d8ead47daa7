"""The ``paris`` assessment report opened in a headless browser: checked, and photographed for the docs.

    python scripts/report_screenshot.py [--duration 300] [--out docs/figures/assessment_report.png]
        [--browser chromium]

Simulates the ``paris`` scenario and assesses it through the command line (``radartracker simulate``,
``radartracker assess``), then opens ``report.html`` in headless Chromium (Debian's ``chromium``
package) twice: once a copy with a script that, after the page's load event, counts the images the browser
decoded (``complete`` with a ``naturalWidth``), the tables and their empty cells, and writes the counts into
the page, which the browser prints back (``--dump-dom``); once to take the screenshot of the top of the page.
Prints the counts as one JSON line and exits 1 unless every image decoded and every cell is filled.
"""

from __future__ import annotations

import argparse
import html
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from radartracker.cli import main as cli

CHECK = """<script>
window.addEventListener("load", () => {
  const images = [...document.images];
  const cells = [...document.querySelectorAll("td, th")];
  const counts = {images: images.length,
                  decoded: images.filter(i => i.complete && i.naturalWidth > 0).length,
                  tables: document.querySelectorAll("table").length,
                  cells: cells.length,
                  empty_cells: cells.filter(c => c.textContent.trim() === "").length,
                  height_px: document.documentElement.scrollHeight};
  document.body.setAttribute("data-check", JSON.stringify(counts));
});
</script>"""


def browser_counts(browser: str, page: Path) -> dict:
    """What the browser made of ``page``: the counts of :data:`CHECK`, read from the DOM it dumps."""
    checked = page.with_name("checked.html")
    checked.write_text(page.read_text(encoding="utf-8").replace("</body>", CHECK + "</body>"), encoding="utf-8")
    dom = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=10000",
                          "--dump-dom", checked.as_uri()], capture_output=True, text=True, timeout=120, check=True)
    found = re.search(r'data-check="([^"]*)"', dom.stdout)
    if found is None:
        raise SystemExit(f"{browser} gave no counts for {page}: {dom.stderr.strip()[-300:]}")
    return json.loads(html.unescape(found.group(1)))


def screenshot(browser: str, page: Path, out: Path, width: int, height: int) -> None:
    """The top ``width`` × ``height`` pixels of ``page`` as a PNG at ``out``."""
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    f"--window-size={width},{height}", f"--screenshot={out}", page.as_uri()],
                   capture_output=True, timeout=120, check=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/assessment_report.png"))
    ap.add_argument("--browser", default="chromium")
    ap.add_argument("--height", type=int, default=2200, help="pixels of the page in the screenshot")
    args = ap.parse_args()
    browser = shutil.which(args.browser)
    if browser is None:
        raise SystemExit(f"no {args.browser} on the PATH (Debian: apt-get install chromium)")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if cli(["--quiet", "simulate", str(root / "paris"), "--scenario", "paris", "--duration", str(args.duration)]):
            return 1
        if cli(["--quiet", "assess", str(root / "paris"), "--out", str(root / "assessment")]):
            return 1
        page = root / "assessment" / "report.html"
        counts = browser_counts(browser, page)
        screenshot(browser, page, args.out.resolve(), 1280, args.height)
    counts["screenshot"] = str(args.out)
    print(json.dumps(counts))
    ok = counts["images"] > 0 and counts["decoded"] == counts["images"] and counts["empty_cells"] == 0
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
