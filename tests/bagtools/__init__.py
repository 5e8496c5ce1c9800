"""Helpers for the bag tests: the rig's topic mix (docs/topics.md) and a publisher process that logs what it sent."""
