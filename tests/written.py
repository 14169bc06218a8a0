"""Measurement sets written as the shop floor writes them: a controller's fixed decimals (0.001 mm, 0.0001 deg,
readings to 0.01 um), tool lengths as a tool table gives them (two tools: 200.000 and 300.000 mm)."""
import numpy as np

from fiveaxis.measurement import instruments as ins
from fiveaxis.measurement.simulate import simulate, to_frame


def controller_csv(model, sim, path):
    """The simulated set as a controller writes it: fixed decimals per column (trailing zeros kept)."""
    df = to_frame(sim, model)
    rotary = {v for v in model.variables if model.machine.axis(v).type == "rotary"}
    fmt = {c: ("%.4f" if c in rotary else "%.3f" if c in ("X", "Y", "Z", "L") else "%.5f"
               if c in ("dx", "dy", "dz", "du") else "%.1f" if c == "t" else "%.10g") for c in df.columns}
    with open(path, "w") as fh:
        fh.write(",".join(df.columns) + "\n")
        for row in df.itertuples(index=False):
            fh.write(",".join("" if isinstance(v, float) and v != v else fmt[c] % v if not isinstance(v, str)
                              else v for c, v in zip(df.columns, row)) + "\n")
    return path


def two_tools(model, effects, n, seed, lengths=(200.0, 300.0)):
    """Tip readings at n random poses, each with one of two tool lengths (a tool table of two tools)."""
    rng = np.random.default_rng(seed)
    plan = ins.plan("tip", model, n, rng, tool_lengths=lengths)
    plan.L = np.where(rng.random(plan.n) < 0.5, *lengths)
    return simulate(model, effects, plan=plan, seed=seed)


#: Sizes of machine errors that no honest printout reaches (issue 29: "an error of 2e7 urad is a bug").
LIMITS = {"nm": 1e6, "um": 1e3, "mm": 1.0, "urad": 1e4, "mrad": 10.0, "rad": 0.01}


def printed_sizes(text: str):
    """Every size a text prints with a length or angle unit: (value, unit, the line), leaving out the places and
    ranges that are positions, not errors ('over the measured range (-999.8 to 999.6 mm)', 'knots every 125 mm
    from -1000 to 1000 mm', 'a period of 2130 mm', 'at its extent of 30 mm', a tool length)."""
    import re
    number = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
    skip = re.compile(r"measured range \([^)]*\)|knots every [^)]*\)|period of " + number + r" \w+|extent of "
                      + number + r" mm|tool lengths? (?:\(mm\) )?[-\d., ]+(?:mm)?|L = " + number + " mm|besides "
                      + number + " mm|covers " + number + " to " + number + " mm|stroke is " + number + " to "
                      + number + " mm|"
                      r"\((?:" + number + r" to )?" + number + r" (?:mm|deg)\)|strokes? \[[^\]]*\]")
    for line in text.splitlines():
        for m in re.finditer(r"(" + number + r") ?(nm|um|mm|urad|mrad|rad)\b(?!/)", skip.sub("", line)):
            yield float(m.group(1)), m.group(2), line


def too_large(text: str) -> list:
    """The sizes a text prints beyond LIMITS (1 mm, 10,000 urad)."""
    return [(v, u, line) for v, u, line in printed_sizes(text) if abs(v) > LIMITS[u]]
