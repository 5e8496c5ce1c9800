"""The monitor's count of missing samples (stability_monitor/gaps.py) on stamps with jitter, drift and losses.

Independent numbers: the stamps are generated here from the sample indices that were sent, so the true loss is
known exactly; the realtime stamps get the plant's kind of timing errors (a tick late by up to 0.9 Ts, white
jitter of 0.1 Ts, a clock 300 ppm off)."""

from __future__ import annotations

import numpy as np
import pytest

from stability_monitor.gaps import SampleGaps

TS = 1_000_000  # ns: 1 kHz


def count(stamps) -> int:
    g = SampleGaps(TS)
    for t in stamps:
        g.add(int(t))
    return g.lost


def stamps_of(sent: np.ndarray, jitter: float = 0.0, ppm: float = 0.0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = sent * TS * (1.0 + ppm * 1e-6) + 5e9
    t += rng.uniform(-jitter, jitter, sent.size) * TS
    return np.round(t).astype(np.int64)


def test_exact_lockstep_stamps_count_exact_losses():
    sent = np.delete(np.arange(10_000), np.r_[100:125, 4000, 9000:9050])
    assert count(sent * TS) == 25 + 1 + 50
    assert count(np.arange(10_000) * TS) == 0


def test_a_late_tick_is_not_a_lost_sample():
    t = stamps_of(np.arange(5000))
    t[1000] += int(0.9 * TS)  # published 0.9 Ts late: the gap before it is 1.9 Ts
    assert count(t) == 0
    # the per-gap rule it replaces, round(gap / Ts) - 1, counts one
    assert int(np.sum(np.maximum(0, np.round(np.diff(t) / TS) - 1))) == 1


@pytest.mark.parametrize("ppm", [0.0, 300.0, -300.0])
def test_jitter_and_clock_drift_count_only_real_losses(ppm):
    sent = np.arange(200_000)
    lost_at = np.r_[50_000:50_025, 120_000:120_003]
    t = stamps_of(np.delete(sent, lost_at), jitter=0.1, ppm=ppm)
    assert count(t) == lost_at.size


def test_a_restart_starts_a_new_segment_and_keeps_the_earlier_losses():
    first = np.delete(np.arange(3000), np.r_[10:20]) * TS
    second = np.delete(np.arange(3000), np.r_[500:505]) * TS  # the plant restarted: stamps from 0 again
    assert count(np.r_[first, second]) == 15
