"""Independent reference: the seed rotor's closed-loop eigenvalues from ROSS (petrobras/ross).

Run with the reference venv (make ref):  .venv-ref/bin/python tests/reference/ross_modes.py OUT.json 0 1000
Writes JSON {speed_rpm: [[re, im], ...]} of ROSS's eigenvalues (all, unsorted) for the seed rotor of
docs/physics.md#seed-rotor: 6 Euler-Bernoulli elements, rotary inertia, gyroscopics, no shear, the solid disk at node 7,
and the ideal-PD AMBs as base-fixed springs and dampers k_eq = |ks| = 1.388e6 N/m, c_eq = 2000 N s/m at nodes 1, 5.
"""

import contextlib
import json
import sys
import warnings

warnings.filterwarnings("ignore")


def seed_rotor(rs):
    """The seed rotor in ROSS: (rotor, disk).  ross_unbalance.py builds the same one from here."""
    steel = rs.Material(name="amb_rig_steel", rho=7810.0, E=211e9, G_s=81.2e9)
    shaft = [
        rs.ShaftElement(
            L=0.25, idl=0.0, odl=0.03, material=steel, shear_effects=False, rotary_inertia=True, gyroscopic=True
        )
        for _ in range(6)
    ]
    disk = rs.DiskElement.from_geometry(n=6, material=steel, width=0.07, i_d=0.0, o_d=0.5)
    bearings = [
        rs.BearingElement(n=n, kxx=1.388e6, kyy=1.388e6, cxx=2000.0, cyy=2000.0, frequency=None) for n in (0, 4)
    ]
    return rs.Rotor(shaft, [disk], bearings), disk


def main(speeds_rpm):
    import numpy as np
    import ross as rs

    rotor, disk = seed_rotor(rs)
    out = {}
    for rpm in speeds_rpm:
        modal = rotor.run_modal(speed=rpm * np.pi / 30.0, num_modes=4 * rotor.ndof)
        ev = np.asarray(modal.evalues)
        out[str(rpm)] = [[float(z.real), float(z.imag)] for z in ev]
    out["ndof"] = int(rotor.ndof)
    out["disk"] = {"m": float(disk.m), "Ip": float(disk.Ip), "Id": float(disk.Id)}
    return out


if __name__ == "__main__":
    with contextlib.redirect_stdout(sys.stderr):  # ROSS prints CoolProp/REFPROP notices on import
        result = main([float(a) for a in sys.argv[2:]] or [0.0, 1000.0])
    with open(sys.argv[1], "w") as fh:
        json.dump(result, fh)
