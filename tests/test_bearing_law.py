"""Nonlinear AMB force law and touchdown contact (issue 15): linearisation, the derived cubic remainder,
capacity and saturation; contact penetration, direction, damping without adhesion, friction whirl."""

import math

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.magnet import MU0, BearingLaw
from amb_dynamics.touchdown import V_SLIP, contact_forces


@pytest.fixture(scope="module")
def rig(repo):
    return load_config(repo / "config" / "seed_rotor.yaml")


@pytest.fixture(scope="module")
def law(rig):
    return BearingLaw.from_config(rig.bearings)


def derivative(f, h):
    """Fourth-order central difference."""
    return (-f(2 * h) + 8 * f(h) - 8 * f(-h) + f(-2 * h)) / (12 * h)


def test_linearisation_is_ki_and_ks(law):
    dF_di = derivative(lambda h: law.force(0.0, h), 1e-4 * law.i0)
    dF_dx = derivative(lambda h: law.force(h, 0.0), 1e-4 * law.g0)
    assert dF_di == pytest.approx(177.4, rel=1e-9)
    assert dF_dx == pytest.approx(1.388e6, rel=1e-9)  # = -ks: the open-loop negative stiffness


@pytest.mark.parametrize(("xi", "eta"), [(1e-2, 0.0), (0.0, 1e-2), (1e-2, 1e-2), (-2e-2, 1e-2), (5e-3, -3e-2)])
def test_small_amplitude_remainder_is_the_derived_cubic(law, xi, eta):
    """F - (ki i - ks x) = ki i0 [(2 xi^3 + 3 xi^2 eta + xi eta^2) + (3 xi^5 + 5 xi^4 eta + 2 xi^3 eta^2)] + O(7th):
    the series of (1 -+ xi)^-2 = sum (k+1) (+-xi)^k times (1 +- eta)^2, odd terms only."""
    x, i = xi * law.g0, eta * law.i0
    diff = law.force(x, i) - law.linear_force(x, i)
    cubic = law.ki * law.i0 * (2 * xi**3 + 3 * xi**2 * eta + xi * eta**2)
    quintic = law.ki * law.i0 * (3 * xi**5 + 5 * xi**4 * eta + 2 * xi**3 * eta**2)
    if xi:
        assert abs(diff) == pytest.approx(abs(cubic), rel=0.1)  # the cubic is the leading remainder
    else:
        assert abs(diff) <= 1e-12 * abs(law.linear_force(x, i))  # centred rotor: the law is linear in i
    seventh = law.ki * law.i0 * 20 * max(abs(xi), abs(eta)) ** 7
    assert abs(diff - cubic - quintic) <= seventh + 1e-12 * abs(law.linear_force(x, i))


def test_law_is_the_two_magnet_formula(law):
    """Against the issue's formula written out, k from ki = 4 k i0/g0^2 (pole factor inside k), each magnet
    capped at the saturation force."""
    k = 177.4 * law.g0**2 / (4 * law.i0)
    cases = [(3e-4, 2.0, False), (-3e-4, -7.5, False), (1.2e-3, 15.0, True), (-8e-4, -7.5, True)]
    for x, i, saturated in cases:
        plus, minus = k * (law.i0 + i) ** 2 / (law.g0 - x) ** 2, k * (law.i0 - i) ** 2 / (law.g0 + x) ** 2
        assert (max(plus, minus) > law.f_sat) == saturated
        expected = min(plus, law.f_sat) - min(minus, law.f_sat)
        assert law.force(x, i) == pytest.approx(expected, rel=1e-12)


def test_capacity_carries_the_weight_and_lifts_off(rig, law):
    limit = rig.controller.current_limit
    assert law.capacity(limit) == pytest.approx(177.4 / (4 * law.i0) * 4 * law.i0 * limit, rel=1e-9)  # ki*limit
    assert law.capacity(limit) / 1640.5 > 2.0  # AMB5's static load (statics, test_gravity_damping)
    # lifting off the backup bearing: the rotor rests at -clearance (below the centre), the upper magnet pulls
    assert law.capacity(limit, -rig.touchdown.clearance) > 1640.5
    assert law.f_sat == pytest.approx(math.cos(math.radians(22.5)) * 3.3e-3 * 1.2**2 / MU0, rel=1e-12)
    plus, _ = law.magnet_forces(0.9 * law.g0, limit)  # gap nearly closed: the flux saturates
    assert plus == law.f_sat


def test_coil_current_never_reverses(law):
    _, minus = law.magnet_forces(0.0, 1.5 * law.i0)  # i > i0 would reverse the "-" coil
    assert minus == 0.0


CONTACT = {"clearance": 1e-3, "stiffness": 5e7, "damping": 2e4, "friction": 0.1}


def test_no_force_inside_the_clearance():
    res = contact_forces([[0.6e-3, 0.7e-3]], [[1.0, -2.0]], spin=100.0, radius=0.015, **CONTACT)
    assert np.all(res.force == 0.0) and res.penetration[0] < 0 and res.normal[0] == 0.0


def test_static_contact_pushes_back_along_the_normal():
    angle = np.radians(-70)
    n = np.array([np.cos(angle), np.sin(angle)])
    res = contact_forces([1.02e-3 * n], [[0.0, 0.0]], spin=0.0, radius=0.015, **CONTACT)
    assert res.penetration[0] == pytest.approx(2e-5, rel=1e-9)
    np.testing.assert_allclose(res.force[0], -5e7 * 2e-5 * n, rtol=1e-9)


def test_damping_never_pulls():
    r = [[1.001e-3, 0.0]]
    approaching = contact_forces(r, [[0.1, 0.0]], 0.0, 0.015, **CONTACT)
    leaving_fast = contact_forces(r, [[-1.0, 0.0]], 0.0, 0.015, **CONTACT)
    assert approaching.force[0, 0] == pytest.approx(-(5e7 * 1e-6 + 2e4 * 0.1), rel=1e-9)
    assert np.all(leaving_fast.force == 0.0)  # k delta + d v_n < 0: no adhesion


def test_friction_opposes_slip_and_drives_backward_whirl():
    """A journal spinning at +Phi touching at +Y: the race's friction pushes it along -Z (backward)."""
    res = contact_forces([[1.01e-3, 0.0]], [[0.0, 0.0]], spin=100.0, radius=0.015, **CONTACT)
    fn = 5e7 * 1e-5
    np.testing.assert_allclose(res.force[0], [-fn, -0.1 * fn * np.tanh(1.5 / V_SLIP)], rtol=1e-12)
    assert abs(res.force[0, 1]) == pytest.approx(0.1 * fn, rel=1e-9)  # full slip: mu F_n
    # a journal rolling without slip on the race (v_t = -Phi R): no friction
    rolling = contact_forces([[1.01e-3, 0.0]], [[0.0, -1.5]], spin=100.0, radius=0.015, **CONTACT)
    assert rolling.force[0, 1] == pytest.approx(0.0, abs=1e-12)


def test_contact_dissipates_over_an_impact():
    """Enter and leave the ring at the same speed: the work of the contact force on the journal is negative."""
    m, k = 50.0, CONTACT["stiffness"]
    x, v, h, work = 1e-3, 0.05, 1e-7, 0.0
    while x >= 1e-3 or work == 0.0:
        f = contact_forces([[x, 0.0]], [[v, 0.0]], 0.0, 0.015, **CONTACT).force[0, 0]
        work += f * v * h
        v += f / m * h
        x += v * h
        if x < 1e-3 and v < 0:
            break
    assert v < 0 and abs(v) < 0.05 and work < 0
    assert 0.5 * m * v**2 == pytest.approx(0.5 * m * 0.05**2 + work, rel=1e-3)  # the energy books balance
    assert k > 0


def test_several_nodes_at_once_match_the_vector_formula():
    """contact_forces on many nodes at once (in contact or not, approaching or leaving, either spin) equals the
    module docstring's law written here with numpy over all nodes: F = -F_n n + F_t t, F_n = max(k delta + d v.n,
    0), F_t = -mu F_n tanh((v.t + Phi R) / V_SLIP), zero where delta <= 0."""
    rng = np.random.default_rng(7)
    angle = rng.uniform(0.0, 2 * np.pi, 40)
    rho = rng.uniform(0.95e-3, 1.05e-3, 40)
    r = np.column_stack([rho * np.cos(angle), rho * np.sin(angle)])
    v = rng.normal(0.0, 0.3, (40, 2))
    for spin in (-150.0, 0.0, 300.0):
        got = contact_forces(r, v, spin, 0.015, **CONTACT)
        n = r / rho[:, None]
        t = np.column_stack([-n[:, 1], n[:, 0]])
        delta = rho - CONTACT["clearance"]
        fn = np.maximum(CONTACT["stiffness"] * delta + CONTACT["damping"] * np.sum(v * n, axis=1), 0.0)
        fn[delta <= 0.0] = 0.0
        ft = -CONTACT["friction"] * fn * np.tanh((np.sum(v * t, axis=1) + spin * 0.015) / V_SLIP)
        want = -fn[:, None] * n + ft[:, None] * t
        assert 5 < np.count_nonzero(fn) < 35  # both cases are exercised
        np.testing.assert_allclose(got.force, want, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(got.penetration, delta, rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(got.normal, fn, rtol=1e-12, atol=1e-9)
