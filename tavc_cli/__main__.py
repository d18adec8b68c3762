"""Entry point for ``python -m tavc_cli``."""

from tavc_cli.cli import app

if __name__ == "__main__":
    app(prog_name="tavc")
