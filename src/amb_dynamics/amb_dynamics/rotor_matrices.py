"""The rotor's constant matrices, named after their physics (docs/physics.md#fe, #formulations).

One :class:`RotorMatrices` holds them for an element (8 x 8 or 4 x 4), the assembled FE rotor or its modal
reduction (n x n).  The equations of motion combine them with the base rates and the spin (``system.py``):

    D(t) = Phi G + 2 Ox C (+ D_s)
    K(t) = K_B + dOx C - Ox^2 M + Ox Phi P - Oz^2 Kp11 - Oy^2 Kp22 + Oy Oz Kp12 + dPhi H1 + (Oy^2 + Oz^2) K_G

and the paper's printed ``seed`` formulation uses its own Gs, Kp11s, Kp22s, Kp12s and Hs instead of G, Kp11,
Kp22, Kp12 and H1 (no P).  ``SYMBOLS`` maps each field to the symbol docs/physics.md uses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields, replace

import numpy as np

SYMBOLS = {  # field -> symbol in docs/physics.md
    "mass": "M",
    "translational_mass": "Mt",
    "rotary_mass": "Mr",
    "shaft_stiffness": "K_B",
    "gyroscopic": "G",
    "coriolis": "C",
    "spin_roll": "P",
    "centrifugal_z": "Kp11",
    "centrifugal_y": "Kp22",
    "centrifugal_yz": "Kp12",
    "spin_acceleration": "H1",
    "seed_gyroscopic": "Gs",
    "seed_centrifugal_z": "Kp11s",
    "seed_centrifugal_y": "Kp22s",
    "seed_centrifugal_yz": "Kp12s",
    "seed_spin_acceleration": "Hs",
    "axial_stiffening": "K_G",
    "structural_damping": "D_s",
}


@dataclass(frozen=True)
class RotorMatrices:
    """Constant (n, n) matrices of the free rotor in generalised coordinates (none for the bearings)."""

    mass: np.ndarray  # M = Mt + Mr
    translational_mass: np.ndarray  # Mt: consistent mass of rho A (and the disks' m)
    rotary_mass: np.ndarray  # Mr: diametral (rotary) inertia
    shaft_stiffness: np.ndarray  # K_B: bending (and, Timoshenko, shear) stiffness
    gyroscopic: np.ndarray  # G, times the total spin Phi in D
    coriolis: np.ndarray  # C, times 2 Ox in D and dOx in K
    spin_roll: np.ndarray  # P, times Ox Phi in K (derived formulation only)
    centrifugal_z: np.ndarray  # Kp11: softening by Oz^2
    centrifugal_y: np.ndarray  # Kp22: softening by Oy^2
    centrifugal_yz: np.ndarray  # Kp12: cross term, Oy Oz
    spin_acceleration: np.ndarray  # H1, times dPhi (drive_model: cardan)
    seed_gyroscopic: np.ndarray  # Gs: the paper's printed G (= -G)
    seed_centrifugal_z: np.ndarray  # Kp11s
    seed_centrifugal_y: np.ndarray  # Kp22s
    seed_centrifugal_yz: np.ndarray  # Kp12s
    seed_spin_acceleration: np.ndarray  # Hs: the paper's printed H
    axial_stiffening: np.ndarray  # K_G per unit Oy^2 + Oz^2 (axial_stiffening: true)
    structural_damping: np.ndarray | None = None  # D_s (damping.py); None until the structure adds it

    @property
    def n(self) -> int:
        return self.mass.shape[0]

    @classmethod
    def zeros(cls, n: int) -> RotorMatrices:
        return cls(**{f.name: np.zeros((n, n)) for f in fields(cls) if f.name != "structural_damping"})

    def items(self) -> list[tuple[str, np.ndarray]]:
        """(field name, matrix) of every matrix present."""
        return [(f.name, m) for f in fields(self) if (m := getattr(self, f.name)) is not None]

    def map(self, f: Callable[[np.ndarray], np.ndarray]) -> RotorMatrices:
        """The same matrices transformed by ``f`` (a modal projection Psi^T X Psi, a copy)."""
        return replace(self, **{name: f(m) for name, m in self.items()})

    def add_block(self, idx: slice, part: RotorMatrices) -> None:
        """Add an element's matrices at the DOFs ``idx`` (assembly; these arrays are mutable, the fields not)."""
        for name, m in part.items():
            getattr(self, name)[idx, idx] += m

    def symbol(self, name: str) -> np.ndarray:
        """The matrix docs/physics.md calls ``name`` (M, K_B, Kp11s, ...)."""
        for field_name, symbol in SYMBOLS.items():
            if symbol == name:
                return getattr(self, field_name)
        raise KeyError(f"no matrix named {name!r} (symbols: {', '.join(SYMBOLS.values())})")
