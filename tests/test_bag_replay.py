"""Replay with /clock into the stability monitor gives the same monitor output as the live run (issue 7).

A lockstep ``amb-rig`` run records everything (``--bag``), its own monitor included: every reader is matched
before step 0, so the bag holds every input sample and every output of the live monitor.  The case is the seed
rotor's unstable pitch case (0.6 rad, T = pi/omega = 718 Ts, rho = 1.0617) from the paper's 1 mm disk start,
current limit and displacement stop lifted (the linear loop): the live monitor refits 8 times per period and
raises its flag after about 6.6 periods, so 10 periods give dozens of estimates and one flag change.

Then ``amb-bag play`` publishes the bag's input topics only (/clock, /base/imu, /amb_plant/state; never the
monitor's own outputs) into a fresh ``amb-monitor`` started with the live run's params file.  The monitor
takes time from the sample stamps, not from a clock; it runs with ``use_sim_time`` so that it subscribes to the
replayed /clock like any node of a replay (its diagnostics stamps are then simulated time), and ``play
--wait-for-subscribers`` starts only once every replayed topic is matched, so the monitor sees every sample.

Asserted: the same number of estimates, every published multiplier equal to the live one to RTOL relative
(of the estimate's largest modulus; seen here: bit-identical), the same /stability/unstable sequence, and the
same final diagnostics (samples, refits, none lost, rho, verdict, flag time, as the node formats them).

That holds because the monitor's output is a function of the sample stream alone, however DDS batches it (the
node drains all pending base rates, then all pending samples): the two ROS-free tests at the end check this for
the pipeline (any interleaving of /base/imu and the samples gives bit-identical estimates) and for the flag (a
batch of refits publishes every change of the flag, as one-by-one arrival does).
"""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from amb_bag.reader import Bag
from procs import spawn

TS = 2e-4  # the seed config's 5 kHz loop
N = 718  # samples per period T of A(t): pitch 0.6 rad at omega = pi / (N Ts) is unstable (rho = 1.0617)
PERIODS = 10
RTOL = 1e-9  # relative to the estimate's largest |mu|
INPUTS = ["/clock", "/base/imu", "/amb_plant/state"]
OUTPUTS = ["/stability/multipliers", "/stability/unstable", "/diagnostics"]
PLAY_RATE = 2.0  # twice the live pace: 8x kept up here too (samples lost 0), 2x leaves margin under load
MONITOR = "stability_monitor"
COMPARED_KEYS = ("samples", "samples lost", "refits", "restarts", "period (s)", "base period (s)", "forcing",
                 "verdict", "periods used", "rank", "signal rank", "rho", "rho std", "confidence",
                 "estimate time (s)", "flag raised at (s)", "unstable")  # fmt: skip

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"  # the paper's idealised rotor


def record_live_run(venv_bin, tmp_path):
    T = N * TS
    bag = tmp_path / "live"
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--config", str(PAPER), "--duration", repr(PERIODS * T),
           "--motion", "pitch",
           "--amplitude", "0.6", "--frequency", repr(np.pi / T), "--initial-displacement", "1e-3",
           "--set", "controller.current_limit=1e9", "--param", "plant:max_displacement_ratio=1e9",
           "--bag", str(bag), "--log-dir", str(tmp_path / "rig")]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads(proc.stdout)
    return bag, tmp_path / "rig" / "params.yaml", summary


def monitor_status(msg):
    for s in msg.status:
        if s.name == MONITOR:
            return {kv.key: kv.value for kv in s.values} | {"_level": s.level, "_message": s.message}
    return None


def bag_outputs(bag):
    """The live monitor's outputs as recorded: multipliers (list of complex arrays), flags, final diagnostics."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Bool, Float64MultiArray

    from stability_monitor.messages import multipliers_from_message

    out = {"multipliers": [], "flags": [], "diag": []}
    for topic, _type, _log, _pub, data in Bag(bag).messages(OUTPUTS):
        if topic == OUTPUTS[0]:
            out["multipliers"].append(multipliers_from_message(deserialize_message(data, Float64MultiArray)))
        elif topic == OUTPUTS[1]:
            out["flags"].append(deserialize_message(data, Bool).data)
        elif (status := monitor_status(deserialize_message(data, DiagnosticArray))) is not None:
            out["diag"].append(status)
    return out


@pytest.fixture
def listen():
    """``listen()`` starts an in-process node capturing the monitor's outputs (as the recorder did live).

    Started only after the live run, so that it hears the replayed monitor alone.
    """
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Bool, Float64MultiArray

    from stability_monitor.messages import multipliers_from_message

    ctx = rclpy.Context()
    made = {}

    def start():
        rclpy.init(context=ctx)
        node = made["node"] = rclpy.create_node("replay_test_listener", context=ctx)
        keep_all = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)  # fmt: skip
        rec = {"multipliers": [], "flags": [], "diag": []}
        node.create_subscription(Float64MultiArray, OUTPUTS[0],
                                 lambda m: rec["multipliers"].append(multipliers_from_message(m)),
                                 keep_all)  # fmt: skip
        node.create_subscription(Bool, OUTPUTS[1], lambda m: rec["flags"].append(m.data), latched)

        def on_diag(msg):
            if (status := monitor_status(msg)) is not None:
                rec["diag"].append(status)

        node.create_subscription(DiagnosticArray, OUTPUTS[2], on_diag, keep_all)
        executor = made["executor"] = rclpy.executors.SingleThreadedExecutor(context=ctx)
        executor.add_node(node)

        def spin_until(pred, timeout):
            end = time.monotonic() + timeout
            while time.monotonic() < end and not pred():
                executor.spin_once(timeout_sec=0.02)
            return pred()

        rec["spin_until"] = spin_until
        return rec

    try:
        yield start
    finally:
        if "executor" in made:
            made["executor"].shutdown()
        if "node" in made:
            made["node"].destroy_node()
        rclpy.try_shutdown(context=ctx)


def replay(listener, venv_bin, tmp_path, bag, params, samples):
    """Play the bag's inputs into a fresh monitor; return its outputs and the player's log."""
    monitor_cmd = [str(venv_bin / "amb-monitor"), "--ros-args", "--params-file", str(params),
                   "-p", "use_sim_time:=true", "-p", "diagnostics_period_s:=0.2"]  # fmt: skip
    play_cmd = [str(venv_bin / "amb-bag"), "play", str(bag), "--topics", *INPUTS, "--rate", repr(PLAY_RATE),
                "--wait-for-subscribers", "30"]  # fmt: skip
    with spawn(monitor_cmd, tmp_path / "monitor.log") as mon:
        assert listener["spin_until"](lambda: listener["diag"] and listener["flags"], 30), mon.text()
        with spawn(play_cmd, tmp_path / "play.log") as player:
            assert listener["spin_until"](lambda: player.popen.poll() is not None, 120), player.text()[-2000:]
            assert player.popen.returncode == 0, player.text()[-2000:]
            play_log = player.text()

        def caught_up():  # the monitor has taken the last sample
            return listener["diag"][-1].get("samples") == str(samples)

        assert listener["spin_until"](caught_up, 60), (listener["diag"][-1], mon.text()[-2000:])
        assert mon.stop() == 0, mon.text()[-2000:]
    assert listener["spin_until"](lambda: listener["diag"][-1].get("final") == "true", 10), listener["diag"][-1]
    listener["spin_until"](lambda: False, 0.3)  # anything published with the final drain
    return listener, play_log


@pytest.mark.ros
@pytest.mark.slow
def test_replay_into_monitor_equals_live_run(listen, venv_bin, tmp_path):
    bag, params, summary = record_live_run(venv_bin, tmp_path)
    live = bag_outputs(bag)
    live_final = live["diag"][-1]
    assert live_final.get("final") == "true", live_final
    samples = int(live_final["samples"])
    assert samples == PERIODS * N + 1 and live_final["samples lost"] == "0"  # the live monitor saw every step
    rec = summary["nodes"]["recorder"]["values"]
    assert rec["lost total"] == "0"
    # the recorder's CPU (all its threads) is real work and at most its two cores' worth over the run
    assert 0.0 < float(rec["cpu time (s)"]) < 2.0 * summary["run_wall_s"]
    assert rec["scheduling"] == "normal"  # amb-rig's lockstep recorder: --priority normal
    # the run's effective config is in the bag (the plant's latched /amb_plant/config), overrides included
    from amb_bag.runconfig import recorded_config
    from amb_dynamics.config import load_config

    T = N * TS
    expected = load_config(PAPER, ["controller.current_limit=1e9", "base_motion.kind=pitch",
                                   "base_motion.amplitude=0.6", f"base_motion.frequency={np.pi / T!r}"])  # fmt: skip
    assert recorded_config(Bag(bag)) == expected
    n_live = len(live["multipliers"])
    assert n_live >= 30 and n_live == int(live_final["refits"])  # several refits; every one is in the bag
    assert live["flags"] == [False, True]  # the run is unstable: one raise, recorded

    got, play_log = replay(listen(), venv_bin, tmp_path, bag, params, samples)
    topics = Bag(bag).topics
    assert f"published {sum(topics[t].message_count for t in INPUTS)} messages" in play_log
    final = got["diag"][-1]
    assert final["samples"] == str(samples) and final["samples lost"] == "0"

    # same estimates, in the same order
    assert len(got["multipliers"]) == n_live
    for k, (mu, mu_live) in enumerate(zip(got["multipliers"], live["multipliers"], strict=True)):
        assert mu.shape == mu_live.shape, k
        if mu_live.size:
            scale = np.abs(mu_live).max()
            np.testing.assert_allclose(mu, mu_live, rtol=0, atol=RTOL * scale, err_msg=f"estimate {k}")
    # same flag sequence, same final verdict
    assert got["flags"] == live["flags"]
    for key in COMPARED_KEYS:
        assert final.get(key) == live_final.get(key), key
    assert final["_level"] == live_final["_level"] and final["_message"] == live_final["_message"]


# -- the monitor's output is a function of the sample stream, not of how the samples were batched -------------
@pytest.fixture(scope="module")
def stream():
    """Base rates and full-state samples of the unstable case (lockstep-equivalent simulation, no DDS)."""
    from amb_dynamics.config import load_config
    from amb_dynamics.estimator.sim import SnapshotSimulator
    from amb_dynamics.motion import BaseMotion
    from amb_dynamics.sampled import SampledLoop
    from amb_dynamics.structure import build_structure

    cfg = load_config(PAPER)  # the idealised loop the live run ran
    model = build_structure(cfg)
    loop = SampledLoop(model, cfg)
    motion = BaseMotion.single("pitch", 0.6, np.pi / (N * loop.Ts))
    sim = SnapshotSimulator(loop, motion)
    x0 = np.zeros(2 * model.n)
    x0[0] = 1e-4
    run, _ = sim.run(9 * N, sim.initial_state(x0))
    omega, _ = motion.angular_velocity(run.t)
    return {"t": run.t, "x": run.x, "omega": omega.T, "groups": tuple([0] * model.n + [1] * model.n)}


def arrival_orders(k: int) -> dict[str, list[tuple[str, int]]]:
    """Ways the same two streams can reach the monitor ('i' base rate k, 'd' sample k)."""
    lead = 300  # base_motion runs ahead of the plant (lead_samples 200) and is drained first in each batch
    ahead = [("i", j) for j in range(min(lead, k))]
    ahead += [e for j in range(k) for e in ((("i", j + lead),) if j + lead < k else ()) + (("d", j),)]
    return {
        "interleaved": [(c, j) for j in range(k) for c in "id"],
        "samples first in each step": [(c, j) for j in range(k) for c in "di"],
        f"base rates {lead} ahead": ahead,
        "all base rates first": [("i", j) for j in range(k)] + [("d", j) for j in range(k)],
        "all samples first": [("d", j) for j in range(k)] + [("i", j) for j in range(k)],
    }


def test_pipeline_output_does_not_depend_on_arrival_order(stream):
    """The period comes from the same prefix of the base rates and the buffered samples are replayed, so every
    arrival order gives bit-identical estimates (the node drains all pending base rates, then all samples)."""
    from stability_monitor.pipeline import MonitorPipeline, MonitorSettings

    results = {}
    for name, order in arrival_orders(stream["t"].size).items():
        pipe = MonitorPipeline(MonitorSettings(base_forcing=True), stream["groups"])
        out = []
        for kind, j in order:
            if kind == "i":
                out += pipe.on_imu(stream["t"][j], stream["omega"][j])
            else:
                out += pipe.on_sample(stream["t"][j], stream["x"][j])
        results[name] = (pipe.period_estimate, out)
    ref_pe, ref = results["interleaved"]
    assert ref_pe.period == N * TS and len(ref) > 40 and ref[-1].unstable
    for name, (pe, out) in results.items():
        assert pe == ref_pe, name
        assert [e.time for e in out] == [e.time for e in ref], name
        assert [e.unstable for e in out] == [e.unstable for e in ref], name
        for e, r in zip(out, ref, strict=True):
            assert np.array_equal(e.fit.multipliers, r.fit.multipliers), (name, e.time)


def test_flag_follows_every_estimate_of_a_batch():
    """A batch of refits that raises and clears the flag publishes both changes, as one-by-one arrival would."""
    from types import SimpleNamespace

    from amb_ros.diagnostics import Counters
    from stability_monitor.node import MonitorNode

    def estimate(unstable):
        return SimpleNamespace(unstable=unstable, fit=SimpleNamespace(excited=False, multipliers=[]))

    sent = {"multipliers": 0, "flags": []}
    node = SimpleNamespace(flag=False, p={"publish_count": 8}, counters=Counters())
    node.mult_pub = SimpleNamespace(publish=lambda _m: sent.__setitem__("multipliers", sent["multipliers"] + 1))
    node.flag_pub = SimpleNamespace(publish=lambda m: sent["flags"].append(m.data))
    node.set_flag = lambda u: MonitorNode.set_flag(node, u)
    batch = [estimate(u) for u in (False, True, True, False, False)]
    node.pipeline = SimpleNamespace(latest=batch[-1])
    MonitorNode.publish(node, batch)
    assert sent == {"multipliers": 5, "flags": [True, False]} and node.flag is False
