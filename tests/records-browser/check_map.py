#!/usr/bin/env python3
"""The roll map in a real browser: a simulated textile roll is fused and searched for
defects into fresh records, `rollfuse rolls map` draws it, and headless Chromium opens the
SVG; fails unless the map renders (a bar of non-zero size, one mark for each defect of the
map's CSV) with no console error, and saves a screenshot.

Standard library only; Chromium is driven as tests/serve-browser/check.py drives it.

    python3 tests/records-browser/check_map.py --rollfuse target/debug/rollfuse \
        --screenshot /tmp/roll-map.png
"""

import argparse
import base64
import importlib.util
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def browser_helpers():
    """The live page's check: its WebSocket, DevTools page and Chromium start and stop."""
    path = os.path.join(ROOT, "tests", "serve-browser", "check.py")
    spec = importlib.util.spec_from_file_location("serve_check", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(*args):
    done = subprocess.run(args, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {done.stderr.strip()}")
    return done.stdout


def make_map(rollfuse, tmp):
    """Records a simulated textile roll and its defects; the map's SVG and its CSV rows."""
    sim, db = os.path.join(tmp, "sim"), os.path.join(tmp, "records.db")
    strip, svg = os.path.join(tmp, "strip", "roll.png"), os.path.join(tmp, "map.svg")
    run(rollfuse, "simulate", os.path.join(ROOT, "host", "scenes", "textile.toml"), "--out", sim)
    run(rollfuse, "fuse", sim, "--out", strip, "--records", db)
    run(rollfuse, "detect", strip, "--records", db)
    run(rollfuse, "rolls", "map", "1", "--records", db, "--out", svg)
    with open(os.path.join(tmp, "map.csv")) as f:
        rows = f.read().splitlines()[1:]
    return svg, rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rollfuse", required=True)
    ap.add_argument("--chromium", default="chromium")
    ap.add_argument("--screenshot", required=True)
    args = ap.parse_args()
    check = browser_helpers()
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:
        svg, rows = make_map(os.path.abspath(args.rollfuse), tmp)
        browser, ws_url = check.start_chromium(args.chromium, os.path.join(tmp, "profile"))
        try:
            page = check.Page(check.WebSocket(ws_url))
            for domain in ("Runtime", "Log", "Page"):
                page.call(f"{domain}.enable")
            page.call("Page.navigate", url="file://" + svg)
            page.pump(1.5)
            root = page.evaluate("document.documentElement.nodeName")
            bar = page.evaluate(
                "(() => { const r = document.querySelector('rect').getBoundingClientRect();"
                " return [r.width, r.height]; })()")
            marks = page.evaluate("document.querySelectorAll('circle > title').length")
            shot = page.call("Page.captureScreenshot", format="png")
            with open(args.screenshot, "wb") as f:
                f.write(base64.b64decode(shot["data"]))
        finally:
            check.stop_chromium(browser)
    print(f"roll map: <{root}>, bar {bar}, {marks} defect marks, {len(rows)} CSV rows; "
          f"screenshot: {args.screenshot}")
    if page.errors:
        print("FAIL: console errors:\n  " + "\n  ".join(page.errors))
        return 1
    if root != "svg" or not bar or min(bar) <= 0:
        print("FAIL: the map did not render as an SVG with its bar")
        return 1
    if not rows or marks != len(rows):
        print(f"FAIL: {marks} marks on the map for {len(rows)} defects in its CSV")
        return 1
    print("the roll map rendered, a mark for every defect, with no console error")
    return 0


if __name__ == "__main__":
    sys.exit(main())
