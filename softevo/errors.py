"""User-facing errors: a mistake by the user is one clear line and exit code 2, never a traceback."""


class UserError(Exception):
    """A mistake in the user's input (arguments, files, settings).

    The CLI prints ``error: <message>`` and exits with status 2.
    """
