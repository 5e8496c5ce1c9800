"""Node: flexible rotor on AMBs (sampled-data propagator of amb_dynamics); /clock master in lockstep."""
