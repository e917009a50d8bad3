"""The HTML page in a real browser: Debian's ``chromium``, headless, offline, driven from the
command line — nothing is downloaded at run time and no Python driver is needed.

* ``--dump-dom`` with ``--virtual-time-budget`` on ``index.html?selftest=…``: the page's own
  self-test (see :mod:`report.html_page`) records the animated elements at load and 600 ms of
  (virtual) time later, after moving the slider to given crank angles, and every error and
  console error since the page started, into ``<pre id="selftest">``; the test reads it back.
  Chromium's console log (``--enable-logging=stderr``) is checked too.
* ``--screenshot``: the page as a PNG test artifact, written to ``$DWELL_TEST_ARTIFACTS``
  (default ``test-artifacts/`` at the repository root, which git ignores) as ``report.png``.

Skipped, with a message, where chromium is not installed (Debian: ``apt-get install chromium``).
"""

from __future__ import annotations

import html
import json
import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from report.candidate_json import length_key

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed: browser test skipped")

REPO = Path(__file__).resolve().parents[2]
#: Offline and quiet: no sandbox (containers, root), no GPU, no background fetches, every host
#: name unresolvable so a page that tried to load anything would fail and say so.
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-dev-shm-usage",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-default-apps",
    "--disable-extensions",
    "--no-first-run",
    "--no-default-browser-check",
    "--mute-audio",
    "--hide-scrollbars",
    "--host-resolver-rules=MAP * ~NOTFOUND",
)


def _chromium(tmp_path: Path, *args: str, url: str) -> subprocess.CompletedProcess:
    profile = tmp_path / f"profile-{len(list(tmp_path.glob('profile-*')))}"
    cmd = [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)


def _selftest(tmp_path: Path, page: Path, angles: list[int], budget_ms: int = 3000) -> tuple[dict, str]:
    """Run the page's self-test; (its result, chromium's stderr)."""
    proc = _chromium(
        tmp_path,
        "--enable-logging=stderr",
        "--v=0",
        f"--virtual-time-budget={budget_ms}",
        "--dump-dom",
        url=page.as_uri() + "?selftest=" + ",".join(map(str, angles)),
    )
    m = re.search(r'<pre id="selftest">(.*?)</pre>', proc.stdout, flags=re.S)
    assert m, f"self-test did not report (exit {proc.returncode}):\n{proc.stderr[-3000:]}"
    return json.loads(html.unescape(m.group(1))), proc.stderr


def _console_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


def test_page_runs_without_errors_animates_and_follows_the_slider(report_dir, tmp_path):
    out, _ = report_dir
    doc = json.loads((out / "candidates.json").read_text(encoding="utf-8"))
    first = doc["candidates"][0]
    start, end = first["dwells"][0]["interval_deg"]
    in_dwell = round(start + (end - start) % 360 / 2) % 360
    away = (in_dwell + 180) % 360
    result, stderr = _selftest(tmp_path, out / "index.html", [in_dwell, away])

    assert result["errors"] == []
    assert _console_lines(stderr) == []  # the page logs nothing, so any console line is news
    assert result["started"] is True
    assert [r["id"] for r in result["candidates"]] == [f"cand-{c['rank']}" for c in doc["candidates"]]
    for rec, item in zip(result["candidates"], doc["candidates"]):
        cyc = item["cycle"]
        t0, t1 = rec["t0"], rec["t1"]
        # it plays by itself, and the mechanism moved between the two moments
        assert t0["playing"] and t1["playing"]
        assert t1["phi"] != t0["phi"]
        assert not np.allclose(t0["crank"], t1["crank"])
        # the slider pauses it and puts the mechanism where the cycle table has it
        for reading, angle in zip(rec["slider"], (in_dwell, away)):
            assert not reading["playing"]
            assert reading["phi"] == angle and reading["index"] == angle
            k = angle
            np.testing.assert_allclose(reading["crank"], [cyc["A_x"][k], -cyc["A_y"][k]], rtol=1e-5, atol=1e-6)
            if item["output"]["type"] == "RRR":
                np.testing.assert_allclose(reading["output"], [cyc["Q_x"][k], -cyc["Q_y"][k]], rtol=1e-5, atol=1e-6)
            else:  # the slot points from D along ψ
                D = item["output"][f"pivot_{length_key(item['length_unit'])}"]
                psi = math.degrees(math.atan2(-reading["output"][1] - D[1], reading["output"][0] - D[0]))
                assert abs((psi - cyc["psi_deg"][k] + 180) % 360 - 180) < 1e-3
            # the output link is coloured exactly while the output dwells
            assert reading["dwelling"] == reading["section_dwelling"] == cyc["dwelling"][k]
        assert rec["resumed"] is True  # Play starts it again
    # the first candidate's two slider positions are one in and one out of its dwell
    assert [r["dwelling"] for r in result["candidates"][0]["slider"]] == [True, False]


def test_selftest_reports_errors_it_meets(report_dir, tmp_path):
    """Negative control: a page with a broken script says so (the clean run above is not a
    self-test that cannot fail)."""
    out, _ = report_dir
    broken = tmp_path / "broken.html"
    text = (out / "index.html").read_text(encoding="utf-8")
    broken.write_text(text.replace("</body>", "<script>noSuchFunction();</script></body>"), encoding="utf-8")
    result, stderr = _selftest(tmp_path, broken, [10])
    assert any("noSuchFunction" in e for e in result["errors"])
    assert any("noSuchFunction" in line for line in _console_lines(stderr))


def test_screenshot_is_written_as_an_artifact(report_dir, tmp_path):
    import matplotlib.image as mpimg

    out, _ = report_dir
    artifacts = Path(os.environ.get("DWELL_TEST_ARTIFACTS", REPO / "test-artifacts"))
    artifacts.mkdir(parents=True, exist_ok=True)
    shot = artifacts / "report.png"
    shot.unlink(missing_ok=True)
    proc = _chromium(
        tmp_path,
        "--window-size=1280,2400",
        "--virtual-time-budget=1500",
        f"--screenshot={shot}",
        url=(out / "index.html").as_uri(),
    )
    assert shot.exists() and shot.stat().st_size > 10_000, proc.stderr[-3000:]
    img = mpimg.imread(shot)
    assert img.shape[:2] == (2400, 1280)
    assert float(np.std(img[..., :3])) > 0.05  # a page, not a blank


#: Measures the page's layout after load into <pre id="layout"> (injected into a copy of the page).
_LAYOUT_PROBE = """<script>
window.addEventListener('load', function () {
  var r = function (el) { var b = el.getBoundingClientRect(); return [b.left, b.right, b.width]; };
  var table = document.querySelector('table.summary');
  var out = {
    inner: window.innerWidth, page: document.documentElement.scrollWidth,
    table: table ? {client: table.clientWidth, scroll: table.scrollWidth, box: r(table)} : null,
    plots: Array.from(document.querySelectorAll('figure.plot')).map(r),
    mechs: Array.from(document.querySelectorAll('svg.mech')).map(r),
    controls: Array.from(document.querySelectorAll('.controls')).map(r),
    main: r(document.body)
  };
  window.parent.postMessage(JSON.stringify(out), '*');
});
</script>"""

#: Chromium's headless window is at least 500 px wide: the page is shown in a 420 px iframe of
#: a host page, which writes what the probe posts into <pre id="layout">.
_HOST = """<!DOCTYPE html><html><body style="margin:0">
<iframe src="{src}" style="width:420px;height:1600px;border:0;display:block"></iframe>
<script>window.addEventListener('message', function (e) {{
  var pre = document.createElement('pre'); pre.id = 'layout'; pre.textContent = e.data; document.body.appendChild(pre);
}});</script></body></html>"""


def test_page_is_usable_420_px_wide(report_dir, tmp_path):
    """At 420 px the page does not overflow sideways: the summary table scrolls inside its own
    box, plots and the mechanism take the full width, the controls stay on screen. A screenshot
    (the page in a 420 px frame) is written as the artifact ``report-420px.png``."""
    out, _ = report_dir
    page, host = out / "layout-probe.html", out / "layout-host.html"
    page.write_text(
        (out / "index.html").read_text(encoding="utf-8").replace("</body>", _LAYOUT_PROBE + "</body>"), encoding="utf-8"
    )
    host.write_text(_HOST.format(src=page.name), encoding="utf-8")
    artifacts = Path(os.environ.get("DWELL_TEST_ARTIFACTS", REPO / "test-artifacts"))
    artifacts.mkdir(parents=True, exist_ok=True)
    shot = artifacts / "report-420px.png"
    shot.unlink(missing_ok=True)
    try:
        proc = _chromium(
            tmp_path, "--window-size=600,900", "--virtual-time-budget=2000", "--dump-dom", url=host.as_uri()
        )
        _chromium(
            tmp_path, "--window-size=600,1600", "--virtual-time-budget=1500", f"--screenshot={shot}", url=host.as_uri()
        )
    finally:
        page.unlink()
        host.unlink()
    m = re.search(r'<pre id="layout">(.*?)</pre>', proc.stdout, flags=re.S)
    assert m, proc.stderr[-3000:]
    layout = json.loads(html.unescape(m.group(1)))
    inner = layout["inner"]
    assert inner == 420
    assert layout["page"] <= inner  # nothing pushes the page wider than the window
    table = layout["table"]
    assert table["box"][1] <= inner + 0.5 and table["client"] <= inner  # the table's box fits …
    assert table["scroll"] >= table["client"]  # … and its columns scroll inside it
    content = layout["main"][2]
    for left, right, width in layout["plots"] + layout["mechs"]:
        assert right <= inner + 0.5 and left >= -0.5
    for left, right, width in layout["plots"]:
        assert width >= 0.8 * content - 40  # full width, not a thumbnail beside another
    for left, right, width in layout["controls"]:
        assert right <= inner + 0.5
    assert shot.exists() and shot.stat().st_size > 5_000
