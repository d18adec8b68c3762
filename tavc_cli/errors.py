"""The one error type users see.

Anything a user can get wrong (a bad key, a value out of range, a missing results folder) raises
``TavcError``; the command line prints its message as a single ``error: ...`` line and exits
with status 1. Any other exception is a bug and keeps its traceback.
"""


class TavcError(Exception):
    """A user-facing error whose message is exactly one line.

    Args:
        message: What went wrong, naming the key or file involved. Line breaks and runs of
            whitespace are collapsed, so wrapped text from a library still prints as one line.
    """

    def __init__(self, message: str) -> None:
        """Store ``message`` with its whitespace collapsed to single spaces."""
        super().__init__(" ".join(str(message).split()))
