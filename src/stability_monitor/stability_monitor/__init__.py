"""Node and offline CLI: online Floquet multipliers and instability flag."""
