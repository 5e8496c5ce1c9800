"""The monitor's pipeline and ``amb-monitor analyze`` on recorded data, without DDS.

Bags are written here in rosbag2 layout (MCAP + metadata.yaml) from the lockstep-equivalent simulation of the
seed rotor's unstable pitch case (0.6 rad, T = 718 Ts, rho = 1.0617), with the messages the plant and the base
motion publish (state blocks as JointTrajectory, JointState displacement, Imu; bags recorded before the state came
in blocks had one JointState per sample, still read).  The analysis must reproduce the estimator run directly on
the same samples, flag the instability, and give the model value of the recorded motion.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from amb_bag.metadata import FileRecord, TopicRecord, build_metadata, write_metadata
from amb_dynamics.config import load_config
from amb_dynamics.errors import InputError
from amb_dynamics.estimator.sim import SnapshotSimulator
from amb_dynamics.estimator.stream import EstimatorConfig, estimate_series
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure
from stability_monitor.pipeline import MonitorPipeline, MonitorSettings

N, AMPLITUDE, PERIODS = 718, 0.6, 14


@pytest.fixture(scope="module")
def run_data():
    cfg = load_config(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")  # idealised loop
    model = build_structure(cfg)
    loop = SampledLoop(model, cfg)
    T = N * loop.Ts
    motion = BaseMotion.single("pitch", AMPLITUDE, np.pi / T)
    sim = SnapshotSimulator(loop, motion)
    x0 = np.zeros(2 * model.n)
    x0[0] = 1e-4
    run, _ = sim.run(PERIODS * N, sim.initial_state(x0))
    Om, _ = motion.angular_velocity(run.t)
    rho = sampled_floquet(loop, motion, T).max_abs
    return {"model": model, "run": run, "Omega": Om.T, "T": T, "Ts": loop.Ts, "rho": rho}


def ns(t: float, Ts: float) -> int:
    return round(t / Ts) * round(Ts * 1e9)  # the nodes' stamps: k * Ts_ns, exact integers


def state_blocks(data, block: int):
    """(log time, CDR) of the plant's /amb_plant/state blocks, built with rclpy's message classes."""
    run, model, Ts = data["run"], data["model"], data["Ts"]
    out = []
    for a in range(0, run.t.size, block):
        ks = range(a, min(a + block, run.t.size))
        msg = JointTrajectory(joint_names=list(model.dof_names))
        t0 = ns(run.t[a], Ts)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t0, 1_000_000_000)
        for k in ks:
            sec, nsec = divmod(ns(run.t[k], Ts) - t0, 1_000_000_000)
            msg.points.append(JointTrajectoryPoint(positions=run.x[k, : model.n].tolist(),
                                                   velocities=run.x[k, model.n :].tolist(),
                                                   time_from_start=Duration(sec=sec, nanosec=nsec)))  # fmt: skip
        out.append((ns(run.t[ks[-1]], Ts) + 1, serialize_message(msg)))
    return out


def write_bag(path, data, topics=("state", "displacement", "imu"), truncate_to=None, state_block=25):
    """A rosbag2-layout bag folder with the plant's and base motion's messages (raw MCAP writer); state_block=0:
    one JointState per state sample, as bags were recorded before the state came in blocks."""
    path.mkdir()
    mcap_path = path / f"{path.name}_0.mcap"
    run, model = data["run"], data["model"]
    js, imu = JointState(), Imu()
    with open(mcap_path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="test")
        chans = {}
        state_type = "trajectory_msgs/msg/JointTrajectory" if state_block else "sensor_msgs/msg/JointState"
        for key, topic, typ in (("state", "/amb_plant/state", state_type),
                                ("displacement", "/amb/displacement", "sensor_msgs/msg/JointState"),
                                ("imu", "/base/imu", "sensor_msgs/msg/Imu")):  # fmt: skip
            if key in topics:
                sid = w.register_schema(name=typ, encoding="ros2msg", data=b"")
                chans[key] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        blocks = state_blocks(data, state_block) if state_block and "state" in chans else []
        for k, t in enumerate(run.t):
            stamp = ns(t, data["Ts"])
            while blocks and blocks[0][0] <= stamp + 1:
                log_time, raw = blocks.pop(0)
                w.add_message(chans["state"], log_time=log_time, data=raw, publish_time=log_time)
            js.header.stamp.sec, js.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            imu.header.stamp = js.header.stamp
            if "imu" in chans:
                imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = map(float, data["Omega"][k])
                w.add_message(chans["imu"], log_time=stamp, data=serialize_message(imu), publish_time=stamp)
            if "state" in chans and not state_block:
                js.name = list(model.dof_names)
                js.position = run.x[k, : model.n].tolist()
                js.velocity = run.x[k, model.n :].tolist()
                w.add_message(chans["state"], log_time=stamp + 1, data=serialize_message(js), publish_time=stamp)
            if "displacement" in chans:
                js.name, js.velocity = list(model.channels), []
                js.position = run.y[k].tolist()
                w.add_message(chans["displacement"], log_time=stamp + 2, data=serialize_message(js), publish_time=stamp)
        w.finish()
    # rosbag2 metadata as a recorder leaves it (amb_bag's reader checks it against the file's summary)
    with open(mcap_path, "rb") as f:
        summary = make_reader(f).get_summary()
    st = summary.statistics
    topics = [TopicRecord(ch.topic, summary.schemas[ch.schema_id].name, [], "", st.channel_message_counts.get(i, 0))
              for i, ch in summary.channels.items()]  # fmt: skip
    start, end = st.message_start_time, st.message_end_time
    write_metadata(path, build_metadata(topics, [FileRecord(mcap_path.name, start, end - start, st.message_count)]))
    if truncate_to is not None:
        raw = mcap_path.read_bytes()
        mcap_path.write_bytes(raw[: int(len(raw) * truncate_to)])
    return path


@pytest.fixture(scope="module")
def bag(run_data, tmp_path_factory):
    return write_bag(tmp_path_factory.mktemp("bags") / "unstable", run_data)


PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"  # the config the bags were made with


def monitor(venv_bin, *args):
    args = (*args, "--config", PAPER) if args[0] == "analyze" and "--config" not in args else args
    return subprocess.run([str(venv_bin / "amb-monitor"), *map(str, args)], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("velocities", [False, True])
def test_pipeline_equals_the_estimator_on_the_same_samples(run_data, velocities):
    """Period found from the base rates (snapped to 718 samples) + buffering = the estimator run directly, on the
    positions of the state (the default) or on the whole state (``velocities``)."""
    run, model = run_data["run"], run_data["model"]
    groups = tuple([0] * model.n + [1] * model.n)
    pipe = MonitorPipeline(MonitorSettings(base_forcing=True, velocities=velocities), groups)  # forcing from /base/imu
    got = []
    for k, t in enumerate(run.t):
        got += pipe.on_imu(t, run_data["Omega"][k])
        got += pipe.on_sample(t, run.x[k])
    assert pipe.period_estimate.period == N * run_data["Ts"] and pipe.period_estimate.snapped
    assert pipe.forcing == "alternating"
    used = run.x if velocities else run.x[:, : model.n]
    cfg = EstimatorConfig(N * run_data["Ts"], run_data["Ts"], forcing="alternating",
                          scale_groups=groups if velocities else (0,) * model.n)  # fmt: skip
    ref = estimate_series(run.t, used, cfg)
    assert len(got) == len(ref) > 40
    assert [e.time for e in got] == [e.time for e in ref]
    assert np.array_equal([e.fit.rho for e in got], [e.fit.rho for e in ref], equal_nan=True)
    assert got[-1].unstable and abs(got[-1].rho - run_data["rho"]) < 1e-6


def test_pipeline_restarts_with_the_run(run_data):
    run = run_data["run"]
    pipe = MonitorPipeline(MonitorSettings(sensor_only=True, period=run_data["T"], forcing="alternating"))
    first = [e for k in range(run.t.size) for e in pipe.on_sample(run.t[k], run.y[k])]
    assert first[-1].unstable
    second = [e for k in range(run.t.size) for e in pipe.on_sample(run.t[k], run.y[k])]
    assert pipe.restarts == 1
    assert np.array_equal([e.rho for e in second], [e.rho for e in first], equal_nan=True)
    with pytest.raises(InputError, match="not after"):
        pipe.on_sample(run.t[5], run.y[5])


def test_analyze_bag_json_and_plot(bag, run_data, venv_bin, tmp_path):
    out = tmp_path / "rho.png"
    res = monitor(venv_bin, "analyze", bag, "--json", "--plot", out)
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    T = run_data["T"]
    assert doc["period_s"] == pytest.approx(T, rel=1e-12) and doc["forcing"] == "none"  # seed config: no base_forcing
    assert doc["verdict"] == "unstable" and doc["flag_time_s"] <= 8 * T
    assert doc["final"]["rho"] == pytest.approx(run_data["rho"], abs=1e-6)
    assert doc["model"]["rho"] == pytest.approx(run_data["rho"], abs=1e-9)  # motion read back from /base/imu
    assert doc["model"]["motion"]["amplitude_rad"] == pytest.approx(AMPLITUDE, rel=1e-9)
    times = [e["time_s"] for e in doc["estimates"]]
    assert times == sorted(times) and len(times) > 40
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_analyze_reads_bags_with_one_state_message_per_sample(bag, run_data, venv_bin, tmp_path):
    """A bag recorded when /amb_plant/state was a JointState per sample gives the same analysis as the blocks."""
    legacy = write_bag(tmp_path / "legacy", run_data, state_block=0)
    docs = []
    for b in (bag, legacy):
        res = monitor(venv_bin, "analyze", b, "--json")
        assert res.returncode == 0, res.stderr
        docs.append(json.loads(res.stdout))
    assert docs[0]["samples"] == docs[1]["samples"] == run_data["run"].t.size
    assert docs[0]["estimates"] == docs[1]["estimates"] and docs[0]["verdict"] == "unstable"


def test_analyze_sensor_only_and_table(bag, run_data, venv_bin):
    res = monitor(venv_bin, "analyze", bag, "--sensor-only")
    assert res.returncode == 0, res.stderr
    assert "verdict: unstable" in res.stdout and "model rho = 1.0617" in res.stdout


def file_with(path, content: bytes):
    path.write_bytes(content)
    return path


def without_metadata(bag_dir):
    (bag_dir / "metadata.yaml").unlink()
    return bag_dir


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p, d: p / "missing", "does not exist"),
        (lambda p, d: file_with(p / "empty.mcap", b""), "is empty"),
        (lambda p, d: file_with(p / "x.mcap", b"hello, not a bag"), "not an MCAP file"),
        (lambda p, d: write_bag(p / "cut", d, truncate_to=0.5), "truncated or damaged"),
        (lambda p, d: without_metadata(write_bag(p / "nometa", d)), "did not finish"),
        (lambda p, d: p, "not a bag folder"),
        (lambda p, d: write_bag(p / "noimu", d, topics=("state",)), "no /base/imu"),
        (lambda p, d: write_bag(p / "nostate", d, topics=("imu",)), "no /amb_plant/state"),
    ],
)
def test_bad_bags_fail_with_one_line(make, message, run_data, venv_bin, tmp_path):
    res = monitor(venv_bin, "analyze", make(tmp_path, run_data), "--json")
    assert res.returncode != 0
    assert message in res.stderr and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and res.stdout == ""


def test_bad_options(venv_bin, bag):
    res = monitor(venv_bin, "analyze", bag, "--window", "0")
    assert res.returncode != 0 and "Traceback" not in res.stderr


def test_multiplier_message_layout():
    from stability_monitor.messages import multipliers_from_message, multipliers_message

    mu = np.array([1.05 * np.exp(0.3j), 1.05 * np.exp(-0.3j), 0.5])
    msg = multipliers_message(mu, 2)
    assert [d.size for d in msg.layout.dim] == [2, 2] and [d.stride for d in msg.layout.dim] == [4, 2]
    assert list(msg.data) == [mu[0].real, mu[0].imag, mu[1].real, mu[1].imag]
    assert np.array_equal(multipliers_from_message(msg), mu[:2])
    empty = multipliers_message([], 8)
    assert empty.layout.dim[0].size == 0 and len(empty.data) == 0


def test_recorded_motion_of_a_long_record():
    """60 s of /base/imu at 1 kHz with the period off by 1e-7 (what up-crossings give): the phase error alone
    would exceed the single-harmonic tolerance; the refined frequency reproduces the motion."""
    from stability_monitor.analyze import recorded_motion

    A, w, phase = 0.4, 22.3, 0.0
    t = np.arange(60000) * 1e-3
    W = np.zeros((t.size, 3))
    W[:, 2] = A * w * np.cos(w * t + phase)
    motion = recorded_motion(t, W, 2 * np.pi / w * (1 + 1e-7))
    h = motion.harmonics[0]
    assert h.axis == "pitch"
    assert h.frequency == pytest.approx(w, rel=1e-9) and h.amplitude == pytest.approx(A, rel=1e-7)
    with pytest.raises(InputError, match="not a single harmonic"):
        W2 = W.copy()
        W2[:, 2] += 0.01 * A * w * np.cos(3 * w * t)
        recorded_motion(t, W2, 2 * np.pi / w)
