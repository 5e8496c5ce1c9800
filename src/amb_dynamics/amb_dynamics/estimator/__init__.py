"""Floquet multipliers identified from measured samples: what the stability monitor runs (docs/physics.md#estimator).

Modules, in the order the data flow through them:

* :mod:`.period`: the base-motion period from the measured angular velocity;
* :mod:`.stream`: :class:`StreamingEstimator` samples the stream at fixed phases, stacks one period per column
  and refits the one-period map as the window slides (:func:`estimate_series` does it offline);
* :mod:`.fit`: :func:`fit_period_map`, the DMD fit on the signal subspace, and the verdict
  (:class:`VerdictPolicy`, :class:`InstabilityFlag`);
* :mod:`.refine`: the variable-projection refinement of a fit (method 'opt');
* :mod:`.mapfit`: :class:`MapFit`, the verdict names and the forcing regressors shared by the two above;
* :mod:`.sim`: :class:`SnapshotSimulator`, the sampled-data loop with excitation and noise, to test and
  benchmark the estimator against known multipliers.
"""

from .fit import METHODS, InstabilityFlag, VerdictPolicy, fit_period_map
from .mapfit import COLLECTING, INSUFFICIENT, MARGINAL, STABLE, UNSTABLE, MapFit
from .period import PeriodEstimate, estimate_base_period
from .refine import refine_fit
from .sim import SnapshotSimulator, add_measurement_noise
from .stream import Estimate, EstimatorConfig, StreamingEstimator, estimate_series

__all__ = [
    "COLLECTING",
    "INSUFFICIENT",
    "MARGINAL",
    "METHODS",
    "STABLE",
    "UNSTABLE",
    "Estimate",
    "EstimatorConfig",
    "InstabilityFlag",
    "MapFit",
    "PeriodEstimate",
    "SnapshotSimulator",
    "StreamingEstimator",
    "VerdictPolicy",
    "add_measurement_noise",
    "estimate_base_period",
    "estimate_series",
    "fit_period_map",
    "refine_fit",
]
