"""Entry point of the ``tavc`` command and of ``python -m tavc_cli``.

Typer would print a mistyped option or command as a framed usage box; here it is one
``error: ...`` line and exit status 2, like every other mistake (the commands themselves
turn tavc's own errors into one line, `console.user_errors`).

Ctrl-C is one line and exit status 130 at any moment: the command line (Typer, Hydra, the
simulator's modules) is imported inside `main`, still under the handler this module installs
first (one line, and out), so that an interrupt never lands inside a library's
half-built state; once the command is done a second Ctrl-C during the interpreter's exit
ends it at once rather than printing a traceback from the middle of its clean-up.
"""

import _signal  # the interpreter's own: `signal` itself takes long enough to load to be interrupted
import os


def _interrupted_while_loading(signum, frame) -> None:
    """Ctrl-C or SIGTERM before the command line has loaded: nothing is written yet, so one
    line and out."""
    terminated = signum == _signal.SIGTERM
    os.write(2, b"error: terminated\n" if terminated else b"error: interrupted\n")
    os._exit(143 if terminated else 130)


# Ctrl-C and SIGTERM are one line from here on, until `main` (Ctrl-C) and each command (SIGTERM,
# `console.user_errors`) take over. Only the command line runs this module.
_signal.signal(_signal.SIGINT, _interrupted_while_loading)
_signal.signal(_signal.SIGTERM, _interrupted_while_loading)

import signal  # noqa: E402 - after the handler: an interrupt while these load is one line too
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from tavc_cli import compiled_code_home, prune_compiled_code  # noqa: E402
from tavc_cli.errors import interrupts_not_swallowed  # noqa: E402


def main() -> None:
    """Run the command line; a usage error (unknown option or command, a value the option's
    type refuses) is one line, and so is Ctrl-C however early it comes."""
    interrupts_not_swallowed()
    root = Path(__file__).resolve().parent
    if not os.environ.get("NUMBA_CACHE_DIR"):  # a folder of the user's own is theirs to keep
        prune_compiled_code(root, compiled_code_home(root))
    try:
        # loaded under tavc_cli's own handler, where it installed one: an interrupt is then one line
        # and out at once, never an exception raised inside a library's half-built state
        loaded = _load()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        code = _run(*loaded)
    except KeyboardInterrupt:
        code = _interrupted()
    signal.signal(signal.SIGINT, _exit_interrupted)
    sys.exit(code)


def _load() -> tuple:
    """The command line's modules: Typer, the console, the app (Hydra and the simulator's modules
    with it)."""
    # deferred: loaded after the interrupt handler is in place (`main`)
    import typer

    from tavc_cli import console
    from tavc_cli.cli import app

    return typer, console, app


def _run(typer, console, app) -> int:
    # click's UsageError, wherever this Typer keeps click (its own copy, in recent versions)
    usage_error = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")
    try:
        code = app(prog_name="tavc", standalone_mode=False)
    except usage_error as error:
        message = " ".join(error.format_message().split())
        if message:  # none when the help was shown for want of arguments
            print(f"error: {message} (tavc --help)", file=sys.stderr)
        return error.exit_code
    except typer.Abort:
        return _interrupted()
    if code == 130 and not console.shown:  # Typer's own exit on Ctrl-C outside a command's handling
        return _interrupted()
    return code if isinstance(code, int) else 0


def _interrupted() -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # one line, however often Ctrl-C is pressed
    print("error: interrupted", file=sys.stderr)
    return 130


def _exit_interrupted(signum, frame) -> None:
    """Ctrl-C while the interpreter exits: one line, and out at once."""
    os.write(2, b"error: interrupted\n")
    os._exit(130)


if __name__ == "__main__":
    main()
