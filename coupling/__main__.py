"""``python -m hammerbit``: the ``hammerbit`` command line."""
from hammerbit.cli import console

if __name__ == "__main__":
    console()
