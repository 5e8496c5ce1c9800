"""One base error for everything the user can cause (bad config, bad input, bad files).

CLIs catch only :class:`AmbError` and print its one-line message; any other exception is a bug and
keeps its traceback.
"""


class AmbError(Exception):
    """Base class of user-facing errors; the message is one sentence."""


class ConfigError(AmbError):
    """Invalid configuration file or override."""


class InputError(AmbError):
    """Invalid numerical input (NaN, wrong sizes, unsupported combination)."""
