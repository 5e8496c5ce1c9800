"""User-facing errors of the bag tools (bad paths, damaged or foreign files, bad options).

Every message is one sentence; ``amb-bag`` prints it and exits non-zero.  Anything else is a bug and keeps its
traceback.
"""

from amb_dynamics.errors import AmbError


class BagError(AmbError):
    """A bag cannot be read, written or used as asked."""


class BagFormatError(BagError):
    """A file is not an MCAP bag in rosbag2 layout, or it is damaged."""
