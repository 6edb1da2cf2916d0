"""``python -m microfab``: the command-line interface."""

from microfab.cli import app

if __name__ == "__main__":
    app()
