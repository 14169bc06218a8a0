"""The certificate's part of the report's record: who, what, where, when and with what (from the campaign,
`report.campaign`), the environment (stated, and the `temp_<name>` columns of the measurement file), the
statement of uncertainty and the traceability statement. The HTML page, its PDF and the DCC XML are all built
from this record; nothing here is computed again there.
"""
from __future__ import annotations

import datetime as _dt

import numpy as np

#: The coverage factor and probability of every expanded uncertainty the certificate states.
K = 2
COVERAGE_PROBABILITY = 0.95


def sensors(meas) -> list[dict]:
    """Per temperature channel of the measurement file (`temp_<name>` columns, degC; blank cells not read): the
    lowest, mean and highest reading and how many rows read it."""
    out = []
    for name, values in sorted((meas.temps if meas is not None else {}).items()):
        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        if v.size:
            out.append({"name": name, "readings": int(v.size), "min_degC": float(v.min()),
                        "mean_degC": float(v.mean()), "max_degC": float(v.max())})
    return out


def uncertainty_statement(iso: dict | None, fit_scale: str) -> list[str]:
    """The statement of uncertainty, sentence by sentence, true to how each stated U was obtained."""
    lines = [f"The expanded uncertainties U stated in this certificate are standard uncertainties multiplied by the "
             f"coverage factor k = {K}; for a normal distribution the true value lies within value \u00b1 U with a "
             f"probability of about {100 * COVERAGE_PROBABILITY:.0f} %. They were determined in accordance with the GUM "
             f"(JCGM 100:2008).",
             "The uncertainties of the fitted errors are those of the weighted least-squares fit of the model to all "
             "readings (" + {"sigma column": "weighted by the measurement file's sigma column",
                             "estimated from the residual": "the readings' noise estimated from the fit's residual"}.get(
                 fit_scale, fit_scale) + "); they contain the scatter of the readings and its propagation through the "
             "model, not the calibration uncertainty of the instrument itself (see its certificate) nor errors "
             "the model does not contain. Quantities the data determine only relative to others are stated as "
             "such."]
    pos = (iso or {}).get("positioning") or []
    if pos:
        stated = [r for r in pos if (r.get("uncertainty") or {}).get("U_um")]
        if stated:
            lines.append("The uncertainties of the ISO 230-2 figures E, M and B follow the simplified budget of ISO "
                         "230-9 from the stated contributors (measuring device, expansion, misalignment, drift); R "
                         "and A contain the repeatability measured in the test and carry no separate budget.")
        else:
            lines.append("No uncertainty is stated for the ISO 230-2 figures: the ISO 230-9 contributors (measuring "
                         "device, temperature deviation with the expansion coefficient's uncertainty, misalignment, "
                         "drift) were not given.")
    return lines


def block(campaign: dict, meas, iso: dict | None, fit_scale: str, today: _dt.date | None = None) -> dict:
    """The certificate record: the campaign's sections (checked by `campaign.check`), the issue date (default:
    today), the environment with the temperature channels' readings, and the statements."""
    cert = {k: (dict(v) if isinstance(v, dict) else [dict(i) for i in v]) for k, v in campaign.items()}
    head = cert["certificate"]
    head.setdefault("issue_date", (today or _dt.date.today()).isoformat())
    env = cert.setdefault("environment", {})
    env["sensors"] = sensors(meas)
    cert["uncertainty_statement"] = uncertainty_statement(iso, fit_scale)
    cert["traceability"] = ("The measurements are traceable to the SI unit metre through the instruments listed, "
                            "each calibrated as its certificate states.")
    cert["coverage"] = {"k": K, "probability": COVERAGE_PROBABILITY}
    return cert
