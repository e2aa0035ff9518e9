"""The CLI in the test's own process (the console script's process boundary is tested in test_cli.py)."""
from hammerbit.cli.main import main


def run_cli(argv, capsys):
    """``main(argv)`` in-process: (exit code, stdout, stderr); argparse's exits count too."""
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err
