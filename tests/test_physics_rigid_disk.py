"""docs/physics.md#checks: the rigid disk on springs (parameter set P0) through the production one-node model.

Every A matrix comes from ``structure.rigid_disk_model`` -> ``system.closed_loop`` -> ``loop.matrix(c)``; the
expected values are the closed forms of the specification (eigenvalue sets matched optimally, 1e-9) and the
Floquet values of 8.1 (1e-6).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import mathieu_a, mathieu_b

from amb_dynamics import floquet, motion, structure, system
from physics_helpers import (
    P0,
    TILT,
    TRANSLATION,
    block,
    constant_rates,
    even_quartic_roots,
    load,
    matched_error,
    newton_euler_tilt,
    off_block,
    p0_stiffness,
    quadratic_eigenvalues,
    rigid_loop,
)

EIG_TOL = 1e-9  # eigenvalue sets (8.1)
FLOQUET_TOL = 1e-6  # Floquet values (8.1)
LISTED_TOL = 1e-6  # values printed with 6 decimals in the specification
SEED = ("formulation=seed",)
CARDAN = ("drive_model=cardan",)


# ---- T1: constant roll = inertial model seen from a rotating frame -------------------------------------------
@pytest.mark.parametrize(
    ("kc", "c", "listed"),
    [
        (0.0, 0.0, [1.5j, 2.5j, 2.162743j, 4.912743j]),
        (1.0, 0.0, [1.479906j, 2.069535j, 2.578684j, 4.918312j]),
        (1.0, 0.3, [-0.111982 + 1.474604j, -0.030187 + 2.078094j, -0.157509 + 2.564804j, -0.000322 + 4.918293j]),
    ],
    ids=["T1", "T1b", "T1c"],
)
def test_constant_roll_is_rotated_inertial_spectrum(kc, c, listed):
    m, Id, Ip, k, kt = P0["m"], P0["Id"], P0["Ip"], P0["k"], P0["kt"]
    Ox, spin = 0.5, 2.0
    Phi = spin + Ox
    A = rigid_loop(kc=kc, c=c).matrix(constant_rates([Ox, 0, 0], spin))
    got = np.linalg.eigvals(A)
    # complex inertial model, z = v + i w, zeta = ty + i tz
    Mc = np.diag([m, Id]).astype(complex)
    Dc = np.diag([c, -1j * Ip * Phi])
    Kc = np.array([[k - 1j * Ox * c, -1j * kc], [1j * kc, kt]])
    lam_in = quadratic_eigenvalues(Mc, Dc, Kc)
    expected = np.concatenate([lam_in - 1j * Ox, lam_in.conj() + 1j * Ox])
    assert matched_error(got, expected) < EIG_TOL
    listed = np.array(listed)
    assert matched_error(got, np.concatenate([listed, listed.conj()])) < LISTED_TOL


# ---- T2-T5: constant rates, translation and tilt blocks ------------------------------------------------------
def _block_eigs(Omega, spin, idx, Ip=P0["Ip"]):
    A = rigid_loop(Ip=Ip).matrix(constant_rates(Omega, spin))
    assert off_block(A, idx) == 0.0  # kc = 0: translation and tilt decouple exactly
    return np.linalg.eigvals(block(A, idx))


def _translation_expected(Omega):
    m, k = P0["m"], P0["k"]
    Ox, Oy, Oz = Omega
    # (m l^2 + k - m(Ox^2+Oz^2)) (m l^2 + k - m(Ox^2+Oy^2)) - m^2 Oy^2 Oz^2 + 4 m^2 Ox^2 l^2 = 0
    a, b = k - m * (Ox**2 + Oz**2), k - m * (Ox**2 + Oy**2)
    return even_quartic_roots(m * m, m * (a + b) + 4 * m * m * Ox**2, a * b - m * m * Oy**2 * Oz**2)


@pytest.mark.parametrize(
    ("Omega", "listed"),
    [
        ((0.0, 0.0, 1.0), [1.732051j, 2j]),
        ((0.0, 0.0, 3.0), [2.236068, 2j]),
        ((0.5, 0.7, 1.1), [1.196718j, 2.316866j]),
    ],
    ids=["T2-Oz1", "T2-Oz3", "T2b"],
)
def test_translation_block(Omega, listed):
    got = _block_eigs(Omega, 0.0, TRANSLATION)
    expected = _translation_expected(Omega)
    if Omega[0] == 0.0 and Omega[1] == 0.0:  # T2: v: l^2 = Oz^2 - k/m, w: l^2 = -k/m
        m, k, Oz = P0["m"], P0["k"], Omega[2]
        closed = np.sqrt(np.array([Oz**2 - k / m, -k / m], dtype=complex))
        assert matched_error(expected, np.concatenate([closed, -closed])) < EIG_TOL
    assert matched_error(got, expected) < EIG_TOL
    listed = np.array(listed, dtype=complex)
    assert matched_error(got, np.concatenate([listed, -listed])) < LISTED_TOL


@pytest.mark.parametrize(
    ("Ip", "listed"),
    [(P0["Ip"], [2.645751j, 3j]), (0.0, [np.sqrt(13.0) * 1j, 3j])],
    ids=["T3", "T3b-rod"],
)
def test_tilt_block_pitch_rate(Ip, listed):
    Id, kt, Oz = P0["Id"], P0["kt"], 2.0
    got = _block_eigs((0.0, 0.0, Oz), 0.0, TILT, Ip=Ip)
    w_ty = np.sqrt((kt - (Ip - Id) * Oz**2) / Id + 0j)
    w_tz = np.sqrt(kt / Id + 0j)
    expected = 1j * np.array([w_ty, -w_ty, w_tz, -w_tz])
    assert matched_error(got, expected) < EIG_TOL
    listed = np.array(listed, dtype=complex)
    assert matched_error(got, np.concatenate([listed, -listed])) < LISTED_TOL


@pytest.mark.parametrize(
    ("Omega", "listed"),
    [((0.0, 0.0, 2.0), [1.352904j, 5.866826j]), ((0.4, 0.7, 1.1), [1.731415j, 6.033424j])],
    ids=["T4-pitch", "T4-general"],
)
def test_tilt_block_spinning(Omega, listed):
    Id, Ip, kt, spin = P0["Id"], P0["Ip"], P0["kt"], 3.0
    Ox, Oy, Oz = Omega
    Phi = spin + Ox
    g = 2 * Id * Ox - Ip * Phi
    kx = Ip * Phi * Ox - Id * Ox**2
    K11 = kt + kx - (Ip - Id) * Oz**2
    K22 = kt + kx - (Ip - Id) * Oy**2
    K12 = (Ip - Id) * Oy * Oz
    # (Id l^2 + K11)(Id l^2 + K22) - K12^2 + g^2 l^2 = 0
    expected = even_quartic_roots(Id * Id, Id * (K11 + K22) + g * g, K11 * K22 - K12 * K12)
    got = _block_eigs(Omega, spin, TILT)
    assert matched_error(got, expected) < EIG_TOL
    listed = np.array(listed, dtype=complex)
    assert matched_error(got, np.concatenate([listed, -listed])) < LISTED_TOL


def test_tilt_block_roll_rate_T5():
    Id, Ip, kt, Ox = P0["Id"], P0["Ip"], P0["kt"], 1.2
    got = _block_eigs((Ox, 0.0, 0.0), 0.0, TILT)
    root = np.sqrt(Ip**2 * Ox**2 + 4 * Id * kt)
    lam = 1j * np.array([(Ip - 2 * Id) * Ox + root, (Ip - 2 * Id) * Ox - root]) / (2 * Id)
    expected = np.concatenate([lam, lam.conj()])
    assert matched_error(got, expected) < EIG_TOL
    listed = np.array([2.832092j, 3.432092j])
    assert matched_error(got, np.concatenate([listed, -listed])) < LISTED_TOL


# ---- T6: time-varying roll and spin against the inertial solution ---------------------------------------------
T6_Q0 = np.array([0.01, -0.004, 0.003, 0.007])
T6_QD0 = np.array([0.0, 0.02, -0.01, 0.005])
T6_TIMES = np.linspace(0.0, 20.0, 401)


def _t6_rates(t):
    """Omega_x, dOmega_x, phi_dot, phi_ddot of T6."""
    return 0.3 + 0.8 * np.cos(1.7 * t), -0.8 * 1.7 * np.sin(1.7 * t), 2 + 0.5 * np.sin(0.9 * t), 0.45 * np.cos(0.9 * t)


@pytest.fixture(scope="module")
def t6_inertial_in_base():
    """Inertial complex model of T6 integrated, then rotated into the base: (4, len(T6_TIMES)) of q."""
    m, Id, Ip, k, kt, kc = P0["m"], P0["Id"], P0["Ip"], P0["k"], P0["kt"], 1.0

    def rhs(t, y):
        z, zeta, dz, dzeta = y[0::2] + 1j * y[1::2]
        Ox, _, spin, _ = _t6_rates(t)
        ddz = (-k * z + 1j * kc * zeta) / m
        ddzeta = (1j * Ip * (spin + Ox) * dzeta - kt * zeta - 1j * kc * z) / Id
        out = np.array([dz, dzeta, ddz, ddzeta])
        return np.column_stack([out.real, out.imag]).ravel()

    z0 = T6_Q0[0::2] + 1j * T6_Q0[1::2]  # (z, zeta)
    dz0 = T6_QD0[0::2] + 1j * T6_QD0[1::2] + 1j * _t6_rates(0.0)[0] * z0
    y0 = np.concatenate([z0, dz0])
    sol = solve_ivp(
        rhs, (0, 20), np.column_stack([y0.real, y0.imag]).ravel(), "DOP853", T6_TIMES, rtol=1e-12, atol=1e-15
    )
    assert sol.success
    alpha = 0.3 * T6_TIMES + (0.8 / 1.7) * np.sin(1.7 * T6_TIMES)
    zb = (sol.y[0::2][:2] + 1j * sol.y[1::2][:2]) * np.exp(-1j * alpha)  # (z, zeta) in the base
    return np.array([zb[0].real, zb[0].imag, zb[1].real, zb[1].imag])


@pytest.mark.parametrize(
    ("overrides", "ok"),
    [((), True), (CARDAN, False), (SEED, False), ((*SEED, "seed_disk_H=consistent"), False)],
    ids=["T6-derived", "T6-cardan", "T6-seed-literal", "T6-seed-consistent"],
)
def test_time_varying_roll_and_spin_T6(t6_inertial_in_base, overrides, ok):
    loop = system.closed_loop(
        structure.rigid_disk_model(P0["m"], P0["Id"], P0["Ip"], p0_stiffness(kc=1.0), 0.0, cfg=load(*overrides)),
        load(*overrides),
    )
    i_dphi = system.COEFFICIENTS.index("dPhi")

    def rhs(t, x):
        Ox, dOx, spin, dspin = _t6_rates(t)
        c = system.coefficients_from_rates(np.array([Ox, 0, 0]), np.array([dOx, 0, 0]), spin)
        # coefficients_from_rates assumes a constant phi_dot; Phi_dot = phi_ddot + dOmega_x (docs/physics.md#frames)
        c[i_dphi] = dspin + dOx
        return loop.matrix(c) @ x

    sol = solve_ivp(rhs, (0, 20), np.concatenate([T6_Q0, T6_QD0]), "DOP853", T6_TIMES, rtol=1e-12, atol=1e-15)
    assert sol.success
    ref = t6_inertial_in_base
    err = np.abs(sol.y[:4] - ref).max() / np.abs(ref).max()
    if ok:
        assert err < 1e-7
    else:
        assert err > 0.1


# ---- T7: periodic roll of the undamped disk is neutrally stable ----------------------------------------------
T7_OMEGAS = np.arange(0.5, 12.0 + 1e-9, 0.25)


def _roll_sweep(loop):
    """(max |mu|, min |mu|) over T7_OMEGAS, A = 0.25, phi_dot = 2."""
    out = []
    for w in T7_OMEGAS:
        res = floquet.floquet(system.periodic_system(loop, motion.BaseMotion.single("roll", 0.25, w), 2.0))
        assert res.converged
        assert res.period == pytest.approx(2 * np.pi / w, rel=1e-14)
        out.append((res.max_abs, np.abs(res.multipliers).min()))
    return np.array(out)


def _seed_without_H():
    cfg = load(*SEED)
    model = structure.rigid_disk_model(P0["m"], P0["Id"], P0["Ip"], p0_stiffness(kc=1.0), 0.0, cfg=cfg)
    mats = dataclasses.replace(model.matrices, seed_spin_acceleration=np.zeros((4, 4)))
    return system.closed_loop(dataclasses.replace(model, matrices=mats), cfg)


def test_periodic_roll_neutral_T7():
    s = _roll_sweep(rigid_loop(kc=1.0))
    assert np.abs(s - 1.0).max() < FLOQUET_TOL


@pytest.mark.parametrize(
    ("variant", "omega", "rho"),
    [
        ("seed-literal", 8.75, 1.977279),
        ("seed-consistent", 8.75, 1.977279),
        ("seed-no-H", 7.0, 1.115757),
        ("derived-cardan", 10.75, 2.192826),
    ],
    ids=["T7-seed-literal", "T7-seed-consistent", "T7-seed-no-H", "T7-cardan"],
)
def test_periodic_roll_regressions_T7(variant, omega, rho):
    loops = {
        "seed-literal": lambda: rigid_loop(kc=1.0, overrides=SEED),
        "seed-consistent": lambda: rigid_loop(kc=1.0, overrides=(*SEED, "seed_disk_H=consistent")),
        "seed-no-H": _seed_without_H,
        "derived-cardan": lambda: rigid_loop(kc=1.0, overrides=CARDAN),
    }
    s = _roll_sweep(loops[variant]())
    i = int(np.argmax(s[:, 0]))
    assert T7_OMEGAS[i] == pytest.approx(omega)
    assert abs(s[i, 0] - rho) < FLOQUET_TOL


# ---- T8: seed disk + the 4.6 corrections = derived disk ------------------------------------------------------
def test_seed_disk_corrected_equals_derived_T8():
    rng = np.random.default_rng(8)
    cfg_s = load(*SEED)
    i_dphi = system.COEFFICIENTS.index("dPhi")
    worst = 0.0
    for _ in range(100):
        Om, dOm = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        spin, dspin = rng.uniform(-5, 5), rng.uniform(-2, 2)
        m, Id, Ip = rng.uniform(0.5, 2.0), rng.uniform(0.2, 2.0), rng.uniform(0.0, 3.0)
        K_B = p0_stiffness(kc=1.0)
        c = system.coefficients_from_rates(Om, dOm, spin)
        c[i_dphi] = dspin + dOm[0]
        seed = structure.rigid_disk_model(m, Id, Ip, K_B, 0.2, cfg=cfg_s)
        mats = seed.matrices
        assert mats.seed_centrifugal_z[2, 2] == Ip and mats.seed_centrifugal_y[3, 3] == Ip  # the seed's tilt entries
        kp11, kp22 = mats.seed_centrifugal_z.copy(), mats.seed_centrifugal_y.copy()
        kp11[2, 2], kp22[3, 3] = Ip - Id, Ip - Id
        mats = dataclasses.replace(mats, seed_gyroscopic=-mats.seed_gyroscopic, seed_centrifugal_z=kp11,
                                   seed_centrifugal_y=kp22, seed_spin_acceleration=np.zeros((4, 4)))  # fmt: skip
        A_fixed = system.closed_loop(dataclasses.replace(seed, matrices=mats), cfg_s).matrix(c)
        # + Omega_x Phi P_D in K: q'' gains -Omega_x Phi M^-1 P_D, M = diag(m, m, Id, Id), P_D = diag(0, 0, Ip, Ip)
        Phi = spin + Om[0]
        A_fixed[6, 2] -= Om[0] * Phi * Ip / Id
        A_fixed[7, 3] -= Om[0] * Phi * Ip / Id
        A_derived = rigid_loop(kc=1.0, c=0.2, m=m, Id=Id, Ip=Ip).matrix(c)
        worst = max(worst, np.abs(A_derived - A_fixed).max() / np.abs(A_derived).max())
    assert worst < 1e-12


# ---- T9: pitch of the non-spinning disk is a Mathieu equation per block --------------------------------------
def _mathieu_unstable(a: float, q: float, n_max: int = 6) -> bool:
    """Unstable iff a < a0(q) or b_n(q) < a < a_n(q), n <= n_max (q >= 0)."""
    if a < mathieu_a(0, q):
        return True
    return any(mathieu_b(n, q) < a < mathieu_a(n, q) for n in range(1, n_max + 1))


def _pitch_block_rhos(loop, A, w, N=128):
    """rho of the v block and the ty block from the Magnus monodromy (N and 2N steps per period pi/w)."""
    ps = system.periodic_system(loop, motion.BaseMotion.single("pitch", A, w), 0.0)
    assert ps.period == pytest.approx(np.pi / w, rel=1e-14)
    out = []
    for steps in (N, 2 * N):
        Phi = floquet.monodromy(ps, steps)
        rhos = []
        for idx in ([0, 4], [2, 6]):
            assert off_block(Phi, idx) < 1e-12 * np.abs(Phi).max()
            rhos.append(np.abs(np.linalg.eigvals(block(Phi, idx))).max())
        out.append(rhos)
    out = np.array(out)
    assert np.abs(out[1] - out[0]).max() < FLOQUET_TOL / 10  # step doubling converged (docs/physics.md#floquet)
    return out[1]


@pytest.mark.parametrize(("overrides", "rho"), [((), 1.216072), (SEED, 1.000000)], ids=["T9-point", "T9-seed"])
def test_pitch_mathieu_point_T9(overrides, rho):
    Id, Ip, kt, A, w = P0["Id"], P0["Ip"], P0["kt"], 1.0, 2.7
    e = (Ip - Id) / Id
    a, q = kt / (Id * w * w) - e * A * A / 2, e * A * A / 4
    assert (a, q) == pytest.approx((0.984568, 0.125), abs=1e-6)
    assert mathieu_b(1, q) < a < mathieu_a(1, q)
    assert abs(_pitch_block_rhos(rigid_loop(overrides=overrides), A, w)[1] - rho) < FLOQUET_TOL


def test_pitch_mathieu_sweep_T9():
    m, Id, Ip, k, kt, A = P0["m"], P0["Id"], P0["Ip"], P0["k"], P0["kt"], 1.0
    loop = rigid_loop()
    blocks = ((k / m, 1.0), (kt / Id, (Ip - Id) / Id))  # (stiffness/inertia, e) of v and ty
    unstable, mismatches = 0, []
    for w in np.arange(1.2, 5.95 + 1e-9, 0.05):
        rhos = _pitch_block_rhos(loop, A, w)
        for (w2, e), rho, name in zip(blocks, rhos, ("v", "ty"), strict=True):
            expect = _mathieu_unstable(w2 / w**2 - e * A * A / 2, e * A * A / 4)
            unstable += expect
            if floquet.verdict(rho) != ("unstable" if expect else "marginal"):
                mismatches.append((round(w, 2), name, rho))
    assert mismatches == []
    assert unstable == 71


# ---- T10: the derived tilt block is the linearisation of the nonlinear Newton-Euler disk ----------------------
@pytest.mark.parametrize(("overrides", "ok"), [((), True), (SEED, False)], ids=["T10", "T10-seed"])
def test_newton_euler_linearisation_T10(overrides, ok):
    rng = np.random.default_rng(10)
    h = 1e-6
    worst = 0.0
    for _ in range(200):
        Om, dOm = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        spin = rng.uniform(-5, 5)
        Id, Ip, kt = rng.uniform(0.5, 2.0), rng.uniform(0.0, 3.0), rng.uniform(2.0, 20.0)
        cfg = load(*overrides)
        model = structure.rigid_disk_model(1.0, Id, Ip, p0_stiffness(kt=kt), 0.0, cfg=cfg)
        A = block(system.closed_loop(model, cfg).matrix(system.coefficients_from_rates(Om, dOm, spin)), TILT)
        jac = np.column_stack(
            [
                (
                    newton_euler_tilt(h * e, Om, dOm, spin, Id, Ip, kt)
                    - newton_euler_tilt(-h * e, Om, dOm, spin, Id, Ip, kt)
                )
                / (2 * h)
                for e in np.eye(4)
            ]
        )
        worst = max(worst, np.abs(jac - A).max() / np.abs(A).max())
    if ok:
        assert worst < 1e-7
    else:
        assert worst > 1e-2


def test_newton_euler_forcing_T10():
    """The field at x = 0 is the base-motion forcing M^-1 f of the one-node model (disk at x_d = 0)."""
    rng = np.random.default_rng(11)
    cfg = load()
    worst = 0.0
    for _ in range(200):
        Om, dOm = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        spin = rng.uniform(-5, 5)
        Id, Ip, kt = rng.uniform(0.5, 2.0), rng.uniform(0.0, 3.0), rng.uniform(2.0, 20.0)
        loop = system.closed_loop(structure.rigid_disk_model(1.0, Id, Ip, p0_stiffness(kt=kt), 0.0, cfg=cfg), cfg)
        field = newton_euler_tilt(np.zeros(4), Om, dOm, spin, Id, Ip, kt)
        b = loop.Bf @ system.forcing_from_rates(Om, dOm, spin)  # x' = A x + b, b = [0; M^-1 f]
        assert not b[TRANSLATION].any()  # x_d = 0: no translational forcing
        worst = max(worst, np.abs(b[TILT] - field).max() / max(np.abs(field).max(), 1.0))
    assert worst < 1e-12
