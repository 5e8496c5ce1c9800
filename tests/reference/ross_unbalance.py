"""Independent reference: the paper rotor's unbalance response from ROSS (petrobras/ross).

Run with the reference venv (make ref):
    .venv-ref/bin/python tests/reference/ross_unbalance.py OUT.json U PHASE_RAD RPM [RPM ...]
Builds the rotor of tests/reference/ross_modes.py (6 Euler-Bernoulli elements with rotary inertia and
gyroscopics, the solid disk at node 7, the ideal-PD AMBs as k_eq = 1.388e6 N/m, c_eq = 2000 N s/m at nodes 1
and 5), puts the unbalance U (kg m) at PHASE on the disk and writes JSON {rpm: {"<node>_<x|y>": [re, im]}} of
ROSS's complex synchronous response (m, 0-peak) at nodes 1, 5 and 7 (1-based as in amb-rig).
"""

import contextlib
import json
import sys
import warnings

from ross_modes import seed_rotor  # the same rotor (this script's folder is on sys.path)

warnings.filterwarnings("ignore")
NODES = (1, 5, 7)


def main(U, phase, speeds_rpm):
    import numpy as np
    import ross as rs

    rotor, _ = seed_rotor(rs)
    w = np.array(speeds_rpm) * np.pi / 30.0
    resp = rotor.run_unbalance_response(node=6, unbalance_magnitude=U, unbalance_phase=phase, frequency=w)
    fr = np.asarray(resp.forced_resp)
    ndof = rotor.number_dof
    out = {}
    for k, rpm in enumerate(speeds_rpm):
        out[str(rpm)] = {
            f"{node}_{ax}": [float(fr[(node - 1) * ndof + j, k].real), float(fr[(node - 1) * ndof + j, k].imag)]
            for node in NODES
            for j, ax in enumerate(("x", "y"))
        }
    return out


if __name__ == "__main__":
    with contextlib.redirect_stdout(sys.stderr):  # ROSS prints CoolProp/REFPROP notices on import
        result = main(float(sys.argv[2]), float(sys.argv[3]), [float(a) for a in sys.argv[4:]])
    with open(sys.argv[1], "w") as fh:
        json.dump(result, fh)
