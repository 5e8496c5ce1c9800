"""`amb-rig report`: one self-contained HTML file that renders in headless Chromium with every image intact, and
carries the numbers the analyses print; from a recorded run, the monitor's verdict, the vibration zones and the
measured sensitivity beside the model.  Bad input is one line, and no report is left half-written."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import matplotlib.image as mpimg
import numpy as np
import pytest

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.delay_margin import delay_margin, margin_text
from amb_dynamics.structure import build_structure
from helpers import cli_dyn, run_rig

CHART = ["--chart-amplitude", "0:0.4:3", "--chart-frequency", "10:30:3"]


def chromium() -> str:
    exe = shutil.which("chromium")
    assert exe, "chromium is missing: `make test` installs Debian's chromium (apt-get install chromium)"
    return exe


def render(html, tmp_path) -> tuple[dict, np.ndarray]:
    """(body attributes after load, screenshot) of the report in headless Chromium."""
    base = [
        chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--virtual-time-budget=5000",
    ]
    dom = subprocess.run([*base, "--dump-dom", html.as_uri()], capture_output=True, text=True, timeout=120).stdout
    body = re.search(r"<body([^>]*)>", dom)
    assert body, dom[-2000:]
    attrs = dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(1)))
    shot = tmp_path / "shot.png"
    subprocess.run([*base, "--window-size=1200,3000", f"--screenshot={shot}", html.as_uri()],
                   capture_output=True, timeout=120, check=True)  # fmt: skip
    return attrs, mpimg.imread(shot)


def report(venv_bin, args, tmp_path):
    out = tmp_path / "report.html"
    proc = subprocess.run([str(venv_bin / "amb-rig"), "report", *args, *CHART, "--out", str(out)],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)  # fmt: skip
    return proc, out


def test_model_report_renders_and_carries_the_analyses_numbers(tmp_path, venv_bin, capsys):
    proc, out = report(venv_bin, ["--config", str(paper_config_path())], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    html = out.read_text()
    assert "http://" not in html and "https://" not in html and "src='data:image/png;base64," in html
    figures = html.count("<img ")
    assert figures == 3  # Campbell, model S, chart (the paper's rotor has no unbalance: said in its section)
    assert "No unbalance response: the config has no unbalance" in html
    attrs, shot = render(out, tmp_path)
    assert attrs.get("data-images") == str(figures) and attrs.get("data-broken") == "0"
    assert shot.shape[0] == 3000 and shot[..., :3].std() > 0.05  # a page, not a blank
    # each speed's digital-loop line carries the loop's delay margin, as amb_dynamics.delay_margin gives it
    cfg = load_config(paper_config_path())
    assert f"; {margin_text(delay_margin(build_structure(cfg), cfg, 0.0))}." in html
    # the peaks in the table are those of `amb-dynamics sensitivity --controller sampled`
    code = cli_dyn(["sensitivity", "--config", str(paper_config_path()), "--controller", "sampled",
                    "--speed-rpm", "0", "1000", "--band", "1:500", "--json"])  # fmt: skip
    assert code == 0
    for s in json.loads(capsys.readouterr().out)["speeds"]:
        for axis, a in s["axes"].items():
            row = f"<td>{s['speed_rpm']:g}</td><td>{axis}</td><td class='num'>{a['peak_abs']:.4g}</td>"
            assert row in html, row
    # the chart is the digital loop's by default, with the numbers of `amb-dynamics chart --controller sampled`
    code = cli_dyn(["chart", "--config", str(paper_config_path()), "--controller", "sampled", "--motion", "pitch",
                    "--amplitude", CHART[1], "--frequency", CHART[3], "--workers", "1", "--no-cache",
                    "--out", str(tmp_path / "chart.png"), "--json"])  # fmt: skip
    assert code == 0
    chart = json.loads(capsys.readouterr().out)
    assert (f"{chart['points']} points (pitch, the digital loop the rig runs, 5000 Hz, delay 0; error bound per "
            f"point up to {chart['max_error_bound']:.2g}): {chart['unstable_points']} unstable.") in html  # fmt: skip


@pytest.mark.ros
def test_report_of_a_recorded_run(tmp_path, venv_bin):
    """The real rig with a multisine injection on amb1_y and the monitor: every section from the bag."""
    bag = tmp_path / "bag"
    inj = {"kind": "multisine", "axis": "amb1_y", "amplitude": "2e-5", "band_lo_hz": "10", "band_hi_hz": "40",
           "duration_s": "4.0", "resolution_hz": "2.0"}  # fmt: skip
    params = [a for k, v in inj.items() for a in ("--param", f"controller:injection_{k}={v}")]
    argv = ["--duration", "4.2", "--motion", "none", "--bag", str(bag), *params]
    code, _, text = run_rig(tmp_path / "run", venv_bin, argv, timeout=300)
    assert code == 0, text[-2000:]
    proc, out = report(venv_bin, ["--bag", str(bag), "--resolution", "2.0", "--settle", "0.5"], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    html = out.read_text()
    assert html.count("<img ") == 5  # + unbalance response and measured S
    assert "Measured on the running loop" in html and "<td>amb1_y</td>" in html
    assert "The stability monitor" in html and "<td>verdict</td>" in html
    agreement = re.search(r"<td>model agreement</td><td>([\d.]+) % over (\d+) coherent bins", html)
    # nonlinear bearings, modelled at their levitated operating point (amb_dynamics.operating_point)
    assert agreement and float(agreement.group(1)) < 2.0 and int(agreement.group(2)) >= 10
    # the band (10-40 Hz) does not resolve the peak: the model calibrated to it gives the zone, and since the rig
    # is the model, its scales are ~1 and its zone is the model's at the operating speed
    fit = re.search(r"<td>calibrated model</td><td>ki x([\d.]+), ks x([\d.]+), residual ([\d.]+) % RMS", html)
    assert fit and abs(float(fit.group(1)) - 1) < 0.03 and abs(float(fit.group(2)) - 1) < 0.03, fit
    zone = re.search(r"<td>zone at its peak</td><td>([A-D]):", html)
    model_zone = re.search(
        r"<td>1000</td><td>amb1_y</td>(?:<td[^>]*>[^<]*</td>){3}<td[^>]*>([A-D]|unstable)</td>", html
    )
    assert zone and model_zone and zone.group(1) == model_zone.group(1)
    attrs, _ = render(out, tmp_path)
    assert attrs.get("data-images") == "5" and attrs.get("data-broken") == "0"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--bag", "/nonexistent/bag"], "nonexistent"),
        (["--config", "/nonexistent.yaml"], "nonexistent.yaml"),
        (["--set", "controller.rate_hz=-1"], "controller.rate_hz"),
    ],
)
def test_bad_input_is_one_line_and_leaves_no_file(tmp_path, venv_bin, args, message):
    proc, out = report(venv_bin, args, tmp_path)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("amb-rig report:")]
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists() and not list(tmp_path.glob("*.part"))
