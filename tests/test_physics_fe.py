"""docs/physics.md#checks: the FE rotor (seed geometry unless stated): T11-T15, T17, T21, T22.

Matrices come from ``fe.ShaftElement`` / ``fe.DiskElement`` / ``fe.assemble`` / ``structure.build_structure`` and
``system.closed_loop``; expected values are the closed forms and beam-theory results of the specification.
Clamping and the buckling matrix, which the core has no API for, are formed here from the core's matrices.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

from amb_dynamics import fe, motion, structure, system
from amb_dynamics.floquet import monodromy
from amb_dynamics.rotor_matrices import SYMBOLS
from physics_helpers import constant_rates, load, matched_error

FULL = "modal_cutoff=null"  # the FE checks use the full 28-DOF model
V_PLANE = [0, 3, 4, 7]  # element positions of (v1, tz1, v2, tz2)
W_PLANE = [1, 2, 5, 6]  # element positions of (w1, ty1, w2, ty2)
T_SIGN = np.diag([1.0, -1.0, 1.0, -1.0])


# ---- section 2 numbers ---------------------------------------------------------------------------------------
def test_seed_section_and_disk_properties_T11():
    cfg = load(FULL)
    sec = fe.section_of(cfg)
    assert sec.rho_A * 6 * sec.length == pytest.approx(8.280846, abs=1e-6)  # shaft mass
    assert sec.EI == pytest.approx(8389.525, abs=1e-3)
    assert (sec.rho_A, sec.i_d, sec.i_p) == pytest.approx((5.520564, 3.105317e-4, 6.210634e-4), rel=1e-6)
    assert sec.length == 0.25
    dp = fe.disk_props(cfg.disks[0], cfg.shaft.density)
    assert (dp.m, dp.Ip, dp.Id) == pytest.approx((107.344294, 3.354509, 1.721087), abs=1e-6)


# ---- T11: Gauss quadrature vs the closed forms of 4.2 --------------------------------------------------------
def _closed_forms(sec: fe.Section) -> dict[str, np.ndarray]:
    """The 8x8 element matrices from the v-plane closed forms and the block table of docs/physics.md#fe."""
    Le, ra, i_d, i_p, EI = sec.length, sec.rho_A, sec.i_d, sec.i_p, sec.EI
    Mt_v = (
        ra
        * Le
        / 420
        * np.array(
            [
                [156, 22 * Le, 54, -13 * Le],
                [22 * Le, 4 * Le**2, 13 * Le, -3 * Le**2],
                [54, 13 * Le, 156, -22 * Le],
                [-13 * Le, -3 * Le**2, -22 * Le, 4 * Le**2],
            ]
        )
    )
    Mr_v = (
        i_d
        / (30 * Le)
        * np.array(
            [
                [36, 3 * Le, -36, 3 * Le],
                [3 * Le, 4 * Le**2, -3 * Le, -(Le**2)],
                [-36, -3 * Le, 36, -3 * Le],
                [3 * Le, -(Le**2), -3 * Le, 4 * Le**2],
            ]
        )
    )
    K_v = (
        EI
        / Le**3
        * np.array(
            [
                [12, 6 * Le, -12, 6 * Le],
                [6 * Le, 4 * Le**2, -6 * Le, 2 * Le**2],
                [-12, -6 * Le, 12, -6 * Le],
                [6 * Le, 2 * Le**2, -6 * Le, 4 * Le**2],
            ]
        )
    )
    T = T_SIGN
    r, s = i_p / i_d, (i_p - i_d) / i_d
    Z = np.zeros((4, 4))
    # name: (vv, ww, vw, wv)
    table = {
        "Mt": (Mt_v, T @ Mt_v @ T, Z, Z),
        "Mr": (Mr_v, T @ Mr_v @ T, Z, Z),
        "K_B": (K_v, T @ K_v @ T, Z, Z),
        "G": (Z, Z, r * Mr_v @ T, -r * T @ Mr_v),
        "C": (Z, Z, -(Mt_v + Mr_v) @ T, T @ (Mt_v + Mr_v)),
        "P": (r * Mr_v, r * T @ Mr_v @ T, Z, Z),
        "Kp11": (Mt_v, s * T @ Mr_v @ T, Z, Z),
        "Kp22": (s * Mr_v, T @ Mt_v @ T, Z, Z),
        "Kp12": (Z, Z, Mt_v @ T - s * Mr_v @ T, T @ Mt_v - s * T @ Mr_v),
        "H1": (Z, Z, Z, -r * T @ Mr_v),
        # seed (4.5): Gs = -G; Kp11s, Kp22s with r for s; Kp12s with +s; Hs wv = +r T Mr_v
        "Gs": (Z, Z, -r * Mr_v @ T, r * T @ Mr_v),
        "Kp11s": (Mt_v, r * T @ Mr_v @ T, Z, Z),
        "Kp22s": (r * Mr_v, T @ Mt_v @ T, Z, Z),
        "Kp12s": (Z, Z, Mt_v @ T + s * Mr_v @ T, T @ Mt_v + s * T @ Mr_v),
        "Hs": (Z, Z, Z, r * T @ Mr_v),
    }
    out = {}
    for name, (vv, ww, vw, wv) in table.items():
        X = np.zeros((8, 8))
        X[np.ix_(V_PLANE, V_PLANE)] = vv
        X[np.ix_(W_PLANE, W_PLANE)] = ww
        X[np.ix_(V_PLANE, W_PLANE)] = vw
        X[np.ix_(W_PLANE, V_PLANE)] = wv
        out[name] = X
    out["M"] = out["Mt"] + out["Mr"]
    return out


@pytest.mark.parametrize("name", [s for s in SYMBOLS.values() if s not in ("K_G", "D_s")])
def test_element_quadrature_matches_closed_forms_T11(name):
    sec = fe.section_of(load(FULL))
    got = fe.ShaftElement(sec).matrices.symbol(name)
    expected = _closed_forms(sec)[name]
    scale = max(np.abs(expected).max(), np.abs(_closed_forms(sec)["Mr"]).max())
    assert np.abs(got - expected).max() <= 1e-12 * scale


def test_disk_matrices_T11():
    """4.3 and 4.5 disk matrices on [v, w, ty, tz]."""
    m, Ip, Id = 2.0, 3.0, 1.75
    dp = fe.DiskProps(1, m, Ip, Id)
    J, S, U, Lo = (
        np.array([[0, -1], [1, 0]]),
        np.array([[0, 1], [1, 0]]),
        np.array([[0, 1], [0, 0]]),
        np.array([[0, 0], [1, 0]]),
    )
    Z = np.zeros((2, 2))

    def blk(a, b):
        return np.block([[a, Z], [Z, b]])

    expected = {
        "M": np.diag([m, m, Id, Id]),
        "G": blk(Z, -Ip * J),
        "C": blk(m * J, Id * J),
        "P": np.diag([0, 0, Ip, Ip]),
        "Kp11": np.diag([m, 0, Ip - Id, 0]),
        "Kp22": np.diag([0, m, 0, Ip - Id]),
        "Kp12": blk(m * S, (Ip - Id) * S),
        "H1": blk(Z, Ip * U),
        "Gs": blk(Z, Ip * J),
        "Kp11s": np.diag([m, 0, Ip, 0]),
        "Kp22s": np.diag([0, m, 0, Ip]),
        "Kp12s": blk(m * S, (Ip - Id) * S),
    }
    got = fe.DiskElement(dp, "literal").matrices
    for name, X in expected.items():
        np.testing.assert_array_equal(got.symbol(name), X, err_msg=name)
    assert got.gyroscopic[2, 3] == Ip and got.gyroscopic[3, 2] == -Ip  # stated explicitly in 4.3
    np.testing.assert_array_equal(got.seed_spin_acceleration, blk(Z, Ip * Lo))
    np.testing.assert_array_equal(fe.DiskElement(dp, "consistent").matrices.seed_spin_acceleration, blk(Z, -Ip * U))


# ---- T12: cantilever under a tip load -------------------------------------------------------------------------
@pytest.mark.parametrize(
    "overrides", [(FULL,), (FULL, "shaft.length=2.0", "shaft.elements=8")], ids=["T12-seed", "T12-L2"]
)
def test_cantilever_tip_load_T12(overrides):
    cfg = load(*overrides)
    fem = fe.assemble(cfg)
    EI, L, n = fem.section.EI, cfg.shaft.length, fem.n
    K = fem.matrices.shaft_stiffness[4:, 4:]  # clamp node 1: drop its 4 DOFs
    P = 1234.5
    tip = fe.dof_index(cfg.n_nodes, 0) - 4
    for dof, (defl, rot, rot_sign) in {0: (0, 3, +1.0), 1: (1, 2, -1.0)}.items():
        f = np.zeros(n - 4)
        f[tip + dof] = P
        u = np.linalg.solve(K, f)[tip : tip + 4]
        assert u[defl] == pytest.approx(P * L**3 / (3 * EI), rel=1e-9)
        assert u[rot] == pytest.approx(rot_sign * P * L**2 / (2 * EI), rel=1e-9)
        others = [j for j in range(4) if j not in (defl, rot)]
        assert np.abs(u[others]).max() <= 1e-12 * abs(u[defl])


# ---- T13: free-free bare shaft --------------------------------------------------------------------------------
def _free_free_first(elements: int, rotary: bool) -> tuple[float, np.ndarray]:
    cfg = load(FULL, "disks=[]", f"shaft.rotary_inertia={str(rotary).lower()}", f"shaft.elements={elements}")
    fem = fe.assemble(cfg)
    w2 = sla.eigh(fem.matrices.shaft_stiffness, fem.matrices.mass, eigvals_only=True)
    beta_L = brentq(lambda x: np.cos(x) * np.cosh(x) - 1.0, 4.5, 5.0)  # 4.7300407...
    sec = fem.section
    w_exact = beta_L**2 * np.sqrt(sec.EI / (sec.rho_A * cfg.shaft.length**4))
    return w_exact, w2


@pytest.mark.parametrize(("elements", "rel_err"), [(6, 2.45e-4), (12, 1.64e-5), (24, 1.04e-6)], ids=["6", "12", "24"])
def test_free_free_shaft_T13(elements, rel_err):
    w_exact, w2 = _free_free_first(elements, rotary=False)
    assert w_exact == pytest.approx(387.636, abs=5e-4)
    assert np.abs(w2[:4]).max() < 1e-8 * w2[4]  # 4 rigid-body zeros
    assert w2[4] == pytest.approx(w2[5], rel=1e-9)  # the two planes (singular K: ~1e-11 rounding)
    assert np.sqrt(w2[4]) / w_exact - 1 == pytest.approx(rel_err, rel=5e-3)  # 3 significant digits


def test_free_free_shaft_rotary_inertia_T13():
    errs = [np.sqrt(w2[4]) / w - 1 for w, w2 in (_free_free_first(ne, rotary=True) for ne in (12, 24))]
    limit = errs[1] + (errs[1] - errs[0]) / 15  # O(h^4) Richardson extrapolation
    assert limit == pytest.approx(-6.2e-4, abs=0.05e-4)


# ---- T14: clamped-free column buckling ------------------------------------------------------------------------
def test_buckling_T14():
    cfg = load(FULL)
    fem = fe.assemble(cfg)
    int_dpsi2 = fe.ShaftElement(fem.section).tension[0]  # int psi'^T psi' ds
    KG = np.zeros((fem.n, fem.n))
    for e in range(cfg.shaft.elements):
        KG[4 * e : 4 * e + 8, 4 * e : 4 * e + 8] += int_dpsi2
    P = sla.eigh(fem.matrices.shaft_stiffness[4:, 4:], KG[4:, 4:], eigvals_only=True)
    P_euler = np.pi**2 * fem.section.EI / (4 * cfg.shaft.length**2)
    assert P_euler == pytest.approx(9200.14, abs=0.005)
    assert P[0] == pytest.approx(P[1], rel=1e-12)  # both planes
    assert P[0] / P_euler - 1 == pytest.approx(6.5e-6, rel=0.01)


# ---- T15: constant roll of the undamped FE rotor = fixed-base modes seen from the rotating base ---------------
@pytest.mark.parametrize(("formulation", "ok"), [("derived", True), ("seed", False)], ids=["T15", "T15-seed"])
def test_constant_roll_shifts_whirl_T15(formulation, ok):
    cfg = load(FULL, "controller.derivative_gain=0", f"formulation={formulation}")
    model = structure.build_structure(cfg)
    assert model.gains.c_eq == 0.0
    loop, n = system.closed_loop(model, cfg), model.n
    spin, Ox = cfg.spin_rad_s, 0.7
    assert spin == pytest.approx(104.72, abs=5e-3)
    lam, vec = np.linalg.eig(loop.matrix(constant_rates([0.0, 0.0, 0.0], spin + Ox)))
    up = lam.imag > 0
    lam, q = lam[up], vec[:n, up]
    assert lam.size == n  # undamped: n pairs on the imaginary axis
    # forward whirl (+Y toward +Z): sum over nodes of Im(conj(phi_v) phi_w) < 0
    whirl = np.sum(np.imag(np.conj(q[0::4]) * q[1::4]), axis=0)
    amp = np.sum(np.abs(q[0::4]) ** 2 + np.abs(q[1::4]) ** 2, axis=0)
    assert np.abs(whirl / amp).min() > 0.4  # every mode whirls (0.5: circular), none is ambiguous
    shifted = np.where(whirl < 0, lam - 1j * Ox, lam + 1j * Ox)
    expected = np.concatenate([shifted, shifted.conj()])
    got = np.linalg.eigvals(loop.matrix(constant_rates([Ox, 0.0, 0.0], spin)))
    err = matched_error(got, expected)
    if ok:
        assert err < 1e-8
    else:
        assert err > 0.1


# ---- T17: a fixed base gives the matrix exponential ----------------------------------------------------------
@pytest.mark.parametrize("T", [0.01, 0.2], ids=["T17-short", "T17-long"])
def test_fixed_base_monodromy_is_expm_T17(T):
    cfg = load(FULL)
    loop = system.closed_loop(structure.build_structure(cfg), cfg)
    ps = system.periodic_system(loop, motion.BaseMotion.single("none", 0.0, 0.0), cfg.spin_rad_s)
    assert ps.period is None and ps.names == ()
    Phi = monodromy(ps, 64, T=T)
    expected = sla.expm(loop.matrix(constant_rates([0.0, 0.0, 0.0], cfg.spin_rad_s)) * T)
    assert np.abs(Phi - expected).max() <= 1e-10 * np.abs(expected).max()


# ---- T21: periods of A(t) and f(t) ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kind", "period_factor"), [("roll", 2.0), ("pitch", 1.0), ("yaw", 1.0)], ids=["T21-roll", "T21-pitch", "T21-yaw"]
)
@pytest.mark.parametrize("formulation", ["derived", "seed"])
def test_periods_T21(kind, period_factor, formulation):
    cfg = load(FULL, f"formulation={formulation}")
    loop = system.closed_loop(structure.build_structure(cfg), cfg)
    A_amp, w = 0.3, 2.5
    ps = system.periodic_system(loop, motion.BaseMotion.single(kind, A_amp, w), cfg.spin_rad_s)
    T = period_factor * np.pi / w  # docs/physics.md#base-motion: roll 2 pi/w, pitch and yaw pi/w
    assert ps.period == pytest.approx(T, rel=1e-14)
    t = np.linspace(0.0, 2 * T, 23)
    A_t = ps.A(t)
    scale = np.abs(A_t).max()
    variation = np.abs(A_t - A_t[0]).max()  # size of the time-varying part (<< |A|: stiff FE modes)
    assert variation > 0.0
    periodic_err = np.abs(ps.A(t + T) - A_t).max()
    assert periodic_err <= 1e-12 * scale and periodic_err <= 1e-9 * variation
    half = np.abs(ps.A(t + np.pi / w) - A_t).max()
    if kind == "roll":
        assert half > 0.1 * variation  # roll: A(t + pi/w) != A(t)
    else:
        assert half <= 1e-12 * scale and half <= 1e-9 * variation
    f_t = loop.Bf @ ps.forcing(t)
    if kind == "roll":
        assert not f_t.any()  # f == 0 for roll
    else:  # forcing period 2 pi/w, not pi/w
        assert np.abs(loop.Bf @ ps.forcing(t + 2 * np.pi / w) - f_t).max() <= 1e-12 * np.abs(f_t).max()
        assert np.abs(loop.Bf @ ps.forcing(t + np.pi / w) - f_t).max() > 1e-3 * np.abs(f_t).max()


def test_combined_period_T21():
    cfg = load(FULL)
    loop = system.closed_loop(structure.build_structure(cfg), cfg)
    bm = motion.BaseMotion((motion.Harmonic("roll", 0.2, 1.5), motion.Harmonic("pitch", 0.3, 1.0)), "combined")
    ps = system.periodic_system(loop, bm, cfg.spin_rad_s)
    T0 = 2 * np.pi / 0.5  # fundamental of 1.5 and 1.0 rad/s
    assert ps.period == pytest.approx(T0, rel=1e-14)
    t = np.linspace(0.0, T0, 31)
    A_t = ps.A(t)
    scale, variation = np.abs(A_t).max(), np.abs(A_t - A_t[0]).max()
    periodic_err = np.abs(ps.A(t + T0) - A_t).max()
    assert periodic_err <= 1e-12 * scale and periodic_err <= 1e-9 * variation
    assert np.abs(ps.A(t + T0 / 2) - A_t).max() > 0.1 * variation


# ---- T22: derived - seed = the table of docs/physics.md#formulations ---------------------------------------
def _slope_integral(cfg, kernel: np.ndarray) -> np.ndarray:
    """sum over elements of int psi'^T kernel psi' ds (n x n), 4-point Gauss with the core's shape functions."""
    sec = fe.section_of(cfg)
    Le, n = sec.length, 4 * cfg.n_nodes
    xg, wg = np.polynomial.legendre.leggauss(4)
    el = np.zeros((8, 8))
    for x, w in zip((xg + 1) / 2, wg * Le / 2, strict=True):
        dpsi = fe.shape_functions(x, Le)[1]
        el += w * dpsi.T @ kernel @ dpsi
    out = np.zeros((n, n))
    for e in range(cfg.shaft.elements):
        out[4 * e : 4 * e + 8, 4 * e : 4 * e + 8] += el
    return out


def _disk_tilt(cfg, values_2x2: np.ndarray) -> np.ndarray:
    n = 4 * cfg.n_nodes
    out = np.zeros((n, n))
    for d in cfg.disks:
        i = fe.dof_index(d.node, 2)
        out[i : i + 2, i : i + 2] += values_2x2
    return out


def test_formulation_identity_T22():
    cfg_d, cfg_s = load(FULL), load(FULL, "formulation=seed")
    md, ms = structure.build_structure(cfg_d), structure.build_structure(cfg_s)
    ld, ls = system.closed_loop(md, cfg_d), system.closed_loop(ms, cfg_s)
    np.testing.assert_array_equal(md.M, ms.M)
    np.testing.assert_array_equal(ld.A0, ls.A0)
    sec = fe.section_of(cfg_d)
    i_d, i_p = sec.i_d, sec.i_p
    dp = fe.disk_props(cfg_d.disks[0], cfg_d.shaft.density)
    I2, E11, E22 = np.eye(2), np.diag([1.0, 0.0]), np.diag([0.0, 1.0])
    S, LOWER = np.array([[0.0, 1.0], [1.0, 0.0]]), np.array([[0.0, 0.0], [1.0, 0.0]])
    n = md.n
    Minv = np.linalg.inv(md.M)

    def a_of_k(dK):  # A contribution of a stiffness term
        A = np.zeros_like(ld.A0)
        A[n:, :n] = -Minv @ dK
        return A

    P = i_p * _slope_integral(cfg_d, I2) + _disk_tilt(cfg_d, dp.Ip * I2)
    Hs = i_p * _slope_integral(cfg_d, LOWER) + _disk_tilt(cfg_d, dp.Ip * LOWER)  # seed_disk_H: literal
    expected = {
        "Phi": -2 * ls.A_terms["Phi"],  # G = -Gs: the gyroscopic sign
        "Ox": 0.0,  # Coriolis 2 Omega_x C: same
        "dOx": 0.0,  # dOmega_x C: same
        "Ox2": 0.0,  # -Omega_x^2 M: same
        "OxPhi": a_of_k(P),  # absent in the seed
        # -Omega_z^2 Kp11: tilts Ip - Id (derived) vs Ip (seed)
        "Oz2": a_of_k(i_d * _slope_integral(cfg_d, E22) + _disk_tilt(cfg_d, dp.Id * E11)),
        "Oy2": a_of_k(i_d * _slope_integral(cfg_d, E11) + _disk_tilt(cfg_d, dp.Id * E22)),
        # shaft Kp12 rotary: -(ip - id) vs +(ip - id) in slopes; disk term identical
        "OyOz": a_of_k(-2 * (i_p - i_d) * _slope_integral(cfg_d, S)),
        "dPhi": a_of_k(Hs),  # seed -Phi_dot Hs, derived (body_axis) none
    }
    scale = max(np.abs(A).max() for A in (*ld.A_terms.values(), *ls.A_terms.values()))
    zero = np.zeros_like(ld.A0)
    for name in system.COEFFICIENTS:
        if name == "Oyz2":
            assert name not in ld.A_terms and name not in ls.A_terms  # axial stiffening off in both
            continue
        diff = ld.A_terms.get(name, zero) - ls.A_terms.get(name, zero)
        assert np.abs(diff - expected[name]).max() <= 1e-12 * scale, name
        assert np.abs(expected[name]).max() == 0.0 or np.abs(diff).max() > 1e-6 * scale, name


# ---- forcing of 4.7 (supports T10/T20): consistent loads reproduce the work of rigid virtual motions -----------
def test_forcing_resultants_4_7():
    """Hermite shapes hold rigid motions exactly, so sum f.delta_q equals the integral of the 4.7 loads."""
    cfg = load(FULL)
    model = structure.build_structure(cfg)
    fem, L = model.fe, cfg.shaft.length
    sec = fem.section
    dp = fem.disks[0]
    x_d = fem.node_x[dp.node - 1]
    x = np.repeat(fem.node_x, 4)
    dof = np.tile(np.arange(4), cfg.n_nodes)
    trans_v, trans_w = (dof == 0) * 1.0, (dof == 1) * 1.0
    rot_v = np.where(dof == 0, x, 0.0) + (dof == 3)  # v = x a, tz = a
    rot_w = np.where(dof == 1, x, 0.0) - (dof == 2)  # w = x b, ty = -b
    inertia = sec.rho_A * L**3 / 3 + sec.i_d * L + dp.m * x_d**2 + dp.Id
    F = model.forcing  # columns a1..a4
    expected = {
        # (force v, moment v-plane, force w, moment w-plane) per unit a_j
        0: (-(sec.rho_A * L**2 / 2 + dp.m * x_d), -inertia, 0.0, 0.0),
        1: (0.0, 0.0, sec.rho_A * L**2 / 2 + dp.m * x_d, inertia),
        2: (0.0, 0.0, 0.0, sec.i_p * L + dp.Ip),
        3: (0.0, sec.i_p * L + dp.Ip, 0.0, 0.0),
    }
    for j, values in expected.items():
        got = [F[:, j] @ shape for shape in (trans_v, rot_v, trans_w, rot_w)]
        np.testing.assert_allclose(got, values, rtol=1e-12, atol=1e-12 * inertia, err_msg=f"a{j + 1}")
