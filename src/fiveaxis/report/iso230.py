"""The report's ISO 230 sections: the ISO 230-2 evaluation of every setup that is a laser run along one linear
axis, and the ISO 230-4 evaluation of every setup that is a ballbar circle, with their plots; setups that are
neither are left to the rest of the report (the reason is kept)."""
from __future__ import annotations

from ..exceptions import InputError
from ..iso230 import circular as C
from ..iso230 import line_groups
from ..iso230 import positioning as P
from ..iso230 import uncertainty as U
from ..plots.iso230 import circle_figure, positioning_figure
from .figures import png


def sections(model, meas, statement: U.Statement | None = None) -> tuple[dict | None, dict]:
    """({"positioning": [ISO 230-2 records], "circles": ISO 230-4 record or None, "skipped": {setup: reasons}} or
    None when no setup is either, figures {name: PNG bytes}). statement: what the test states for ISO 230-9's
    uncertainty of the ISO 230-2 figures (None: nothing stated)."""
    statement = statement or U.Statement()
    positioning, circles, skipped = [], [], {}
    try:
        groups = line_groups(meas, "")
    except InputError:                        # no 1-D readings: neither standard applies
        return None, {}
    for setup, idx in groups:
        part = meas.subset(idx)
        reasons = []
        try:
            positioning += [P.to_json(ev, U.budget(statement, ev.length_mm) or U.none_statement())
                            for ev in P.evaluate(part, model)]
            continue
        except InputError as exc:
            reasons.append(f"ISO 230-2: {exc}")
        try:
            circles += C.evaluate(part, model)
            continue
        except InputError as exc:
            reasons.append(f"ISO 230-4: {exc}")
        skipped[str(setup)] = reasons
    if not positioning and not circles:
        return None, {}
    rec = {"positioning": positioning, "circles": C.to_json(circles) if circles else None, "skipped": skipped}
    figs = {f"iso230_2_{i}": png(positioning_figure(r)) for i, r in enumerate(positioning)}
    if circles:
        figs.update({f"iso230_4_{i}": png(circle_figure(c)) for i, c in enumerate(rec["circles"]["circles"])})
    return rec, figs
