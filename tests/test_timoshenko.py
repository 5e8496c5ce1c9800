"""Timoshenko option (docs/physics.md#timoshenko): shear against the analytic cantilever, and its EB limit."""

from dataclasses import replace

import numpy as np
import pytest

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.fe import ShaftElement, assemble, section_of


def cantilever_tip(cfg, P=1000.0):
    """Clamp node 1, load P along +Y at the last node: (v_tip, theta_z_tip)."""
    K = assemble(cfg).matrices.shaft_stiffness
    free = np.arange(4, K.shape[0])
    f = np.zeros(K.shape[0])
    f[-4] = P
    q = np.zeros(K.shape[0])
    q[free] = np.linalg.solve(K[np.ix_(free, free)], f[free])
    return q[-4], q[-1]


@pytest.mark.parametrize("elements", [1, 6])
def test_timoshenko_cantilever_has_the_shear_deflection(elements):
    """v_tip = P L^3/(3 EI) + P L/(kappa G A), theta_z = P L^2/(2 EI): exact for the shear-locking-free element."""
    overrides = [
        "shaft.model=timoshenko",
        "modal_cutoff=null",
        f"shaft.elements={elements}",
        f"disks.0.node={elements + 1}",
        "bearings.nodes=[1, 2]",
        "shaft.diameter=0.2",
    ]  # stubby: shear matters
    cfg = load_config(paper_config_path(), overrides)
    sec = section_of(cfg)
    L, P = cfg.shaft.length, 1000.0
    v, tz = cantilever_tip(cfg, P)
    bending, shear = P * L**3 / (3 * sec.EI), P * L / sec.kGA
    assert shear / bending > 5e-3
    assert v == pytest.approx(bending + shear, rel=1e-10)
    assert tz == pytest.approx(P * L**2 / (2 * sec.EI), rel=1e-10)


def test_timoshenko_element_tends_to_euler_bernoulli():
    """phi_s -> 0 (shear stiffness -> infinity at fixed EI): every element matrix tends to the EB one, O(phi_s)."""
    eb = section_of(load_config(paper_config_path()))
    errors = []
    for kGA in (1e12, 1e14):
        timo = ShaftElement(replace(eb, kGA=kGA)).matrices
        ref = ShaftElement(eb).matrices
        errors.append(max(np.abs(getattr(timo, k) - getattr(ref, k)).max() / np.abs(getattr(ref, k)).max()
                          for k in ("mass", "shaft_stiffness", "gyroscopic", "centrifugal_z")))  # fmt: skip
    assert errors[1] < 1e-7
    assert errors[0] / errors[1] == pytest.approx(100.0, rel=0.05)


def test_timoshenko_kappa_of_a_solid_circle():
    cfg = load_config(paper_config_path(), ["shaft.model=timoshenko"])
    sec = section_of(cfg)
    nu = cfg.shaft.youngs_modulus / (2 * cfg.shaft.shear_modulus) - 1
    kappa = 6 * (1 + nu) / (7 + 6 * nu)
    area = np.pi * cfg.shaft.diameter**2 / 4
    assert sec.kGA == pytest.approx(kappa * cfg.shaft.shear_modulus * area, rel=1e-15)
    assert 0.88 < kappa < 0.9  # Cowper's value for a solid circle with nu ~ 0.3
