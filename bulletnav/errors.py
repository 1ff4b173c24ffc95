"""Typed exceptions raised by the library (the CLI turns them into messages and exit codes)."""


class BulletnavError(Exception):
    """Base class of every error bulletnav raises on purpose."""


class LayoutError(BulletnavError, ValueError):
    """A layout file or procedural layout request is invalid (message names file and field)."""


class SamplingError(BulletnavError, RuntimeError):
    """No valid start/goal pair could be drawn in a layout."""


class DisplayError(BulletnavError, RuntimeError):
    """A GUI was requested but no X display is reachable."""


class ModelError(BulletnavError, ValueError):
    """A model file is missing, truncated or of the wrong kind."""


class RunError(BulletnavError, ValueError):
    """A training-run directory is missing or incomplete."""


class ConfigError(BulletnavError, ValueError):
    """A hyperparameter or configuration file is missing or malformed (message names file and key)."""


class LimitError(BulletnavError, ValueError):
    """A size or count exceeds its resource limit (:mod:`bulletnav.limits`); the message names the
    field, the value, the limit and the environment variable that raises it."""
