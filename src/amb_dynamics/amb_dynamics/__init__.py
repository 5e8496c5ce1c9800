"""ROS-free numerical core of amb-rig: FE rotor on AMBs on a moving base, Floquet, Newmark, digital loop.

The public API is listed in ``__all__`` and described in docs/api.md.  Names are loaded on first use (PEP 562),
so ``import amb_dynamics`` is cheap and has no side effects: it neither imports numpy nor changes
``os.environ``.  Entry points call :func:`amb_dynamics.threads.limit_blas_threads` before numpy loads.
"""

from __future__ import annotations

import importlib
from typing import Any

# public name -> submodule that defines it ("module:attribute" where the public name differs: the functions
# floquet.floquet and newmark.newmark share their module's name, which the package attribute already holds)
_API = {
    # configuration and errors
    "load_config": "config",
    "config_from_dict": "config",
    "seed_config_path": "config",
    "RotorConfig": "config",
    "AmbError": "errors",
    "ConfigError": "errors",
    "InputError": "errors",
    # model
    "ShaftElement": "fe",
    "DiskElement": "fe",
    "RotorMatrices": "rotor_matrices",
    "build_structure": "structure",
    "StructuralModel": "structure",
    "closed_loop": "system",
    "ClosedLoop": "system",
    "periodic_system": "system",
    "PeriodicSystem": "system",
    "BaseMotion": "motion",
    "Harmonic": "motion",
    "load_recorded": "recorded",
    # analyses
    "modes_at_speed": "modes",
    "campbell_data": "modes",
    "ModalResult": "modes",
    "floquet_multipliers": "floquet:floquet",
    "sampled_floquet": "floquet",
    "orbit_floquet": "forced_orbit",
    "aperiodic_exponents": "floquet",
    "FloquetResult": "floquet",
    "stability_chart": "chart",
    "ChartResult": "chart",
    "newmark_response": "newmark:newmark",
    "disk_initial_state": "newmark",
    "fit_growth_rate": "newmark",
    "NewmarkRun": "newmark",
    # the digital loop the nodes run
    "SampledLoop": "sampled",
    "SampledRun": "sampled",
    "DiscretePID": "amb",
    # controllers and sensitivity (ISO 14839-3)
    "StateSpace": "state_space",
    "close_loop": "state_space",
    "continuous_controller": "control_law",
    "discrete_controller": "control_law",
    "ControlLaw": "control_runtime",
    "loop_state_spaces": "sensitivity",
    "sensitivity_matrix": "sensitivity",
    "fit_sensitivity": "sensitivity_fit",
    "levitated_operating_point": "operating_point:operating_point",
    # the online estimator
    "StreamingEstimator": "estimator",
    "EstimatorConfig": "estimator",
    "estimate_series": "estimator",
    "estimate_base_period": "estimator",
    # process set-up for entry points
    "limit_blas_threads": "threads",
}

__all__ = sorted(_API)


def __getattr__(name: str) -> Any:
    target = _API.get(name)
    if target is None:
        raise AttributeError(f"module 'amb_dynamics' has no attribute '{name}'")
    module, _, attribute = target.partition(":")
    value = getattr(importlib.import_module(f".{module}", __name__), attribute or name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
