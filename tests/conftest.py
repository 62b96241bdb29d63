"""What the tests share: the test robots (robots.py) on the path, the command-line runner, z-scores."""

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))


@pytest.fixture
def cli(capsys):
    """``cli(*argv) -> (exit code, stdout, stderr)``: the ``robocal`` command run in-process."""
    from robocal.cli import main

    def run(*argv):
        code = main([str(a) for a in argv])
        out, err = capsys.readouterr()
        return code, out, err
    return run


def z_scores(result, true, nominal):
    """(estimate - truth) / reported std of each identified parameter; rotation corrections are
    compared as the correction that turns ``nominal``'s stored rotations into the truth's."""
    import robocal as rc

    names = rc.parameter_names(true)
    truth = dict(zip(names, rc.parameter_vector(true, nominal)))
    return np.array([(p.estimate - truth[p.name]) / p.std for p in result.parameters])


def assert_one_line_error(code, err, words, out_dir=None, command="calibrate"):
    """A bad input: exit 2, one line on stderr naming ``words``, no traceback, nothing written."""
    assert code == 2 and "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"robocal {command}: error: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert out_dir is None or not out_dir.exists()
