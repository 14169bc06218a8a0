"""The adversarial corpus (tests/adversarial.py, issue 19): a fast subset here, the whole corpus with --fuzz
(`make fuzz` prints its table). Every trial runs the command line as a subprocess under a memory limit and a
timeout; none may run code, end in a traceback or hang, or pass nonsense silently."""
import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import adversarial as A  # noqa: E402

BAD = ("code-execution", "traceback", "hang", "silent")


def _run(tmp_path, selected, jobs=2):
    if shutil.which("prlimit") is None:
        pytest.skip("prlimit (util-linux) is missing: the corpus runs every trial under a memory limit")
    results = A.run_all(A.Runner(tmp_path), selected, jobs=jobs, progress=False)
    return results, A.table(results)


def test_the_corpus_is_large_and_covers_every_command():
    trials = A.trials()
    assert len(trials) >= 400 and len({t.id for t in trials}) == len(trials)
    from fiveaxis.cli import COMMANDS
    assert set(COMMANDS) <= {t.command for t in trials}, set(COMMANDS) - {t.command for t in trials}


@pytest.mark.slow
def test_fast_subset(rs274, tmp_path):
    selected = [t for t in A.trials() if t.id in A.FAST]
    assert len(selected) == len(A.FAST)
    results, text = _run(tmp_path, selected)
    totals = A.totals(results)
    assert not any(totals[c] for c in BAD + ("vague", "refused-valid")), text


@pytest.mark.fuzz
def test_full_corpus(rs274, tmp_path):
    results, text = _run(tmp_path, A.trials())
    print(text)
    totals = A.totals(results)
    assert not any(totals[c] for c in BAD), text
