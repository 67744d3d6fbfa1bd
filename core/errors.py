"""User-facing errors.

Everything a user can get wrong (bad images, impossible configurations, missing files) raises a
subclass of :class:`UserError` with a one-line message that says what is wrong and how to fix it.
The CLI prints that line and exits with status 2; the Python API lets it propagate.
"""


class UserError(ValueError):
    """A problem with the user's input, configuration or files (CLI exit status 2)."""


class ConfigError(UserError):
    """An unknown key, a value of the wrong type or out of range, or an impossible combination."""


class InputError(UserError):
    """An image, ground truth, mask or scene folder that cannot be used."""
