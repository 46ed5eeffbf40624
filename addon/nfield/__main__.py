"""``python -m nfield``: the command line (see nfield.cli)."""
import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
