"""``python -m hammerbit``: the ``hammerbit`` command line."""
import sys

from hammerbit.cli import main

if __name__ == "__main__":
    sys.exit(main())
