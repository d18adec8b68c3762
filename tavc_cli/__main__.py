"""Entry point of the ``tavc`` command and of ``python -m tavc_cli``.

Typer would print a mistyped option or command as a framed usage box; here it is one
``error: ...`` line and exit status 2, like every other mistake (the commands themselves
turn tavc's own errors into one line, `cli._user_errors`).
"""

import sys

import typer

from tavc_cli.cli import app

# click's UsageError, wherever this Typer keeps click (its own copy, in recent versions)
_USAGE_ERROR = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")


def main() -> None:
    """Run the command line; a usage error (unknown option or command, a value the option's
    type refuses) is one line."""
    try:
        code = app(prog_name="tavc", standalone_mode=False)
    except _USAGE_ERROR as error:
        message = " ".join(error.format_message().split())
        if message:  # none when the help was shown for want of arguments
            print(f"error: {message} (tavc --help)", file=sys.stderr)
        sys.exit(error.exit_code)
    except typer.Abort:
        print("error: interrupted", file=sys.stderr)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
