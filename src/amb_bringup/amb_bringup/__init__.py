"""amb-rig: starts the nodes as separate processes (no launch system) and summarises a run."""
