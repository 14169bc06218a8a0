"""The calibration loop, written once: diagnose, add the top candidate, diagnose again, while the decision says an
effect is missing and names one, at most `max_rounds` diagnoses.

`fiveaxis diagnose FILE --rounds N` prints it (`report.text.rounds`), `fiveaxis report` builds its rounds from it,
and `make run` (scripts/run-main.sh) shows it on the examples.
"""
from __future__ import annotations

from ..estimation.problem import resolve_effects
from ..exceptions import InputError
from . import diagnose as D

#: Rounds of diagnose -> add the top candidate, at most, unless told otherwise.
MAX_ROUNDS = 4


def rounds(model, meas, effects, max_rounds: int = MAX_ROUNDS, top: int = 10, fixed=None,
           in_blocks: bool | None = None, prior=None, progress=None, stages=None) -> list:
    """The diagnoses of the loop, in order ([Diagnosis]): round 1 with `effects`, each next round with the previous
    round's best candidate added, until a round's verdict is not "missing effect" (or it lists no candidate) or
    `max_rounds` diagnoses ran. top, fixed, in_blocks, prior, stages: as for `diagnose`; progress: None, or called
    after each round with (its number, max_rounds, its Diagnosis, the id added next or None: the loop ends)."""
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, int) or max_rounds < 1:
        raise InputError(f"rounds: expected a whole number >= 1, got {max_rounds!r}")
    out = []
    effects = list(effects)
    for k in range(1, max_rounds + 1):
        dg = D.diagnose(model, meas, effects, top=top, fixed=fixed, in_blocks=in_blocks, prior=prior, stages=stages)
        out.append(dg)
        last = not (dg.missing_effect and dg.candidates) or k == max_rounds
        if progress is not None:
            progress(k, max_rounds, dg, None if last else dg.candidates[0]["id"])
        if last:
            break
        effects = effects + resolve_effects(model, [dg.candidates[0]["id"]], poses=meas.poses)
    return out


def round_line(k: int, most: int, dg, added) -> str:
    """The line that says a round of the loop is done (a `rounds` progress call's arguments), for a log."""
    then = f"adding {added}" if added else "the loop ends"
    return f"diagnose round {k} of at most {most}: {dg.verdict} (residual RMS {1e3 * dg.rms_mm:.3g} um); {then}"
