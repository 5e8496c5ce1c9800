"""Preflight of the digital loop: the issue's new-user rotor (tests/configs/new_user_rotor.yaml) is stable as a
continuous loop and unstable as the 5 kHz digital loop the rig runs; `modes`/`campbell` flag it, `amb-rig run`
refuses it (or warns with --force).  The spectral radius is checked against an independent time simulation."""

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import pytest

from amb_dynamics import cli
from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.preflight import digital_at_rest, stable_rate
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

ROOT = Path(__file__).resolve().parents[1]
NEW_USER = ROOT / "tests" / "configs" / "new_user_rotor.yaml"


@pytest.fixture(scope="module")
def new_user():
    cfg = load_config(NEW_USER)
    return cfg, build_structure(cfg)


def growth_per_sample(model, cfg, rate_hz: float, steps: int = 400) -> float:
    """|x_k|^(1/k) growth of the at-rest loop from a 1 um disk push: SampledLoop.simulate, no eigenvalues."""
    loop = SampledLoop(model, cfg, Ts=1.0 / rate_hz, forcing=False)
    x0 = np.zeros(2 * model.n)
    x0[: model.n] = np.random.default_rng(1).standard_normal(model.n) * 1e-6
    run = loop.simulate(BaseMotion(), steps, x0)
    n = np.linalg.norm(run.x, axis=1)
    half = steps // 2  # the second half: the dominant pole has taken over
    return float((n[-1] / n[-1 - half]) ** (1 / half))


def test_new_user_rotor_digital_loop_unstable_continuous_stable(new_user):
    cfg, model = new_user
    d = digital_at_rest(model, cfg)
    assert not d["stable"] and d["spectral_radius_per_sample"] > 1.1
    assert growth_per_sample(model, cfg, 5000.0) == pytest.approx(d["spectral_radius_per_sample"], rel=1e-3)
    assert cli.main(["floquet", "--config", str(NEW_USER), "--json"]) == 0  # continuous: stable (issue: 0.967)


def test_stable_rate_is_stable_in_simulation(new_user):
    cfg, model = new_user
    rate = stable_rate(model, cfg)
    assert rate is not None and rate > cfg.controller.rate_hz
    assert digital_at_rest(model, cfg, rate)["stable"]
    assert growth_per_sample(model, cfg, rate, steps=1500) <= 1.0


def test_modes_and_campbell_flag_it(capsys, tmp_path):
    assert cli.main(["modes", "--config", str(NEW_USER), "--speed-rpm", "0", "1000", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [s["digital_loop"]["stable"] for s in data["speeds"]] == [False, False]
    assert all(s["stable"] for s in data["speeds"])  # the continuous loop is stable
    png = tmp_path / "c.png"
    assert cli.main(["campbell", "--config", str(NEW_USER), "--speeds", "0:3000:4", "--out", str(png)]) == 0
    assert "WARNING: the digital loop (5000 Hz, delay 0) is UNSTABLE at 4 of 4 speeds" in capsys.readouterr().out
    assert cli.main(["modes", "--speed-rpm", "1000", "--json"]) == 0  # the seed rotor: stable
    assert json.loads(capsys.readouterr().out)["speeds"][0]["digital_loop"]["stable"]


def test_rig_refuses_in_under_5_s(capsys):
    from amb_bringup import rig

    t0 = time.monotonic()
    with pytest.raises(SystemExit) as exc:
        rig.main(["run", "--config", str(NEW_USER), "--duration", "1"])
    assert time.monotonic() - t0 < 5.0
    assert exc.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "refusing to run" in lines[0] and "UNSTABLE" in lines[0]
    assert "--set controller.rate_hz=" in lines[0]


def test_rig_force_warns_and_goes_on(capsys):
    from amb_bringup import rig

    with pytest.raises(SystemExit) as exc:  # --rt-priority with the monitor is refused right after the preflight
        rig.main(["run", "--config", str(NEW_USER), "--duration", "1", "--force", "--rt-priority", "5"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "WARNING (--force)" in err and "--rt-priority" in err


def test_modes_judge_the_digital_loop_the_rig_runs(capsys):
    """The paper's config runs its digital loop on the modal model (modal_cutoff 5000 rad/s): `modes` must give
    that loop's verdict (the one `amb-rig run` checks), not the full FE model's, whose 1.8 kHz mode is unstable."""
    from amb_dynamics.config import paper_config_path
    from amb_dynamics.preflight import rig_preflight

    cfg = load_config(paper_config_path())
    assert cli.main(["modes", "--config", str(paper_config_path()), "--speed-rpm", "0", "1000", "--json"]) == 0
    speeds = json.loads(capsys.readouterr().out)["speeds"]
    ok, _ = rig_preflight(cfg)
    assert ok and [s["digital_loop"]["stable"] for s in speeds] == [True, True]
    want = digital_at_rest(build_structure(cfg), cfg)["spectral_radius_per_sample"]  # at the config's 1000 rpm
    assert speeds[1]["digital_loop"]["spectral_radius_per_sample"] == pytest.approx(want, rel=1e-12)
    full = digital_at_rest(build_structure(dataclasses.replace(cfg, modal_cutoff=None)), cfg)
    assert not full["stable"]  # the full model at 5 kHz: why the cutoff exists
