#!/usr/bin/env python3
"""Drives headless Chromium (Debian's, through Playwright) on hilcam's live page for
tests/serve/live.rs. Commands on stdin, one JSON answer per command on stdout:

  frame N       wait until the page shows frame N (header and image); answer the
                brightness centroid of the displayed image (its natural pixels), its mean,
                and its size
  counters      wait until every counter row on the page equals /metrics; answer both
  screenshot P  save a screenshot of the whole page to P
"""
import argparse
import json
import sys
import time
import urllib.request

from playwright.sync_api import sync_playwright

# The displayed image's pixels, read back through a canvas (same origin: not tainted).
IMAGE_STATS = """() => {
  const img = document.getElementById('frame');
  const w = img.naturalWidth, h = img.naturalHeight;
  if (!w || !h) return null;
  const c = document.createElement('canvas'); c.width = w; c.height = h;
  const g = c.getContext('2d'); g.drawImage(img, 0, 0);
  const d = g.getImageData(0, 0, w, h).data;
  let s = 0, sx = 0, sy = 0;
  for (let i = 0; i < w * h; i++) {
    const v = d[4 * i];
    s += v; sx += v * ((i % w) + 0.5); sy += v * (Math.floor(i / w) + 0.5);
  }
  return { width: w, height: h, mean: s / (w * h), centroid: s > 0 ? [sx / s, sy / s] : null };
}"""

COUNTER_ROWS = """() => Object.fromEntries([...document.querySelectorAll('#counters tr')]
  .map((tr) => [tr.dataset.key, tr.lastChild.textContent]))"""


def metrics(base):
    text = urllib.request.urlopen(base + "/metrics", timeout=10).read().decode()
    out = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            key, value = line.rsplit(" ", 1)
            out[key] = value
    return out


def wait(what, check, timeout=30.0, every=0.2):
    deadline = time.monotonic() + timeout
    while True:
        got = check()
        if got is not None:
            return got
        if time.monotonic() > deadline:
            raise SystemExit(f"browser.py: timed out waiting for {what}")
        time.sleep(every)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--chromium", required=True)
    ap.add_argument("--base", required=True, help="http://host:port of the metrics listener")
    a = ap.parse_args()
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=a.chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1280, "height": 820})
        page.goto(a.base + "/live", wait_until="domcontentloaded")
        for line in sys.stdin:
            cmd, _, arg = line.strip().partition(" ")
            if cmd == "frame":
                n = arg
                last = [None]

                def shown():
                    if page.inner_text("#frame-seq") != n or page.inner_text("#shown-seq") != n:
                        return None
                    last[0] = page.evaluate(IMAGE_STATS)
                    return last[0] if last[0] and last[0]["mean"] > 0 else None
                try:
                    answer = wait(f"frame {n} shown on the page", shown)
                except SystemExit as e:
                    img = page.evaluate("() => { const i = document.getElementById('frame');"
                                        " return [document.readyState, i.src, i.complete, i.naturalWidth]; }")
                    viewers = metrics(a.base).get("hilcam_live_viewers")
                    raise SystemExit(f"{e}; last read of the image: {last[0]}; (page state, src, complete,"
                                     f" width): {img}; viewers on /metrics: {viewers}")
            elif cmd == "counters":
                diff = [None]

                def agree():
                    shown = page.evaluate(COUNTER_ROWS)
                    m = metrics(a.base)
                    diff[0] = {k: (v, m.get(k)) for k, v in shown.items() if m.get(k) != v}
                    if shown and not diff[0]:
                        return {"page": shown, "metrics": {k: m.get(k) for k in shown}}
                    return None
                try:
                    answer = wait("the page's counters to equal /metrics", agree, every=0.5)
                except SystemExit as e:
                    raise SystemExit(f"{e}; (page, /metrics) that differ: {diff[0]}")
            elif cmd == "screenshot":
                page.screenshot(path=arg)
                answer = {"saved": arg}
            else:
                raise SystemExit(f"browser.py: unknown command {line!r}")
            print(json.dumps(answer), flush=True)
        browser.close()


if __name__ == "__main__":
    main()
