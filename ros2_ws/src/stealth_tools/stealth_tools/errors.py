"""The one error the CLI turns into a single line on stderr and exit status 1."""


class CommandError(Exception):
    """A user-facing failure: the message says what was wrong and, if it helps, what exists."""
