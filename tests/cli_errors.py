"""The CLI error contract the tests check: exit status 1 and one line on stderr naming the problem."""
from __future__ import annotations

from training.cli import main


def fails(capsys, argv: list[str], *needles: str) -> str:
    """Run the CLI: exit status 1 and one line on stderr, 'imufmu VERB: error: ...', containing
    every needle; returns the line."""
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 1, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"imufmu {argv[0]}: error:"), err
    for n in needles:
        assert n in err, err
    return err
