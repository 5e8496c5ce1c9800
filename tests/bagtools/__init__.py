"""Helpers for the bag tests: the DESIGN.md topic mix and a publisher process that logs what it sent."""
