"""The measurement uncertainty of ISO 230-2's E, M and B: the simplified budget of ISO 230-9 (GUM type B
estimates combined in quadrature, expanded with k = 2) from what the user states about the test.

Contributors (standard uncertainties, um), for a measured length L (mm, first to last target):
- the measuring device: u_DEVICE as stated (its calibration certificate: U / k, at the measured length);
- the machine's expansion coefficient: the machine was at a temperature deviating by dT (K) from 20 degC, and
  its expansion coefficient is known within +-d_alpha (ppm/K) (rectangular): u_EMT = L dT d_alpha / sqrt(3)
  (the nominal expansion itself is compensated by the device's material temperature input);
- misalignment of the beam and the axis: a lateral walk w (mm) of the beam over the measured length makes a
  cosine error between 0 and c = w^2 / (2 L) (rectangular over that range): u_MISALIGNMENT = c / (2 sqrt(3));
- environmental variation (drift of the reading of a still axis over the time of a test, EVE, um; rectangular
  over its range): u_EVE = EVE / (2 sqrt(3)).
E and M are ranges of deviations over the measured length: every contributor enters,
    U(E) = U(M) = 2 sqrt(u_DEVICE^2 + u_EMT^2 + u_MISALIGNMENT^2 + u_EVE^2).
B is the difference of the two directions at one target: the device's scale, the expansion and the cosine error
are the same for both and cancel; only the drift between the two approaches enters, U(B) = 2 u_EVE.
The figures R and A contain the repeatability measured in the test itself; no budget is given for them.
Without any statement there is no uncertainty statement, and the figures say so.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..exceptions import InputError

#: The figures with a budget.
FIGURES = ("E", "M", "B")
NONE_STATEMENT = ("no uncertainty statement: the measuring device's uncertainty, the temperature deviation with the "
                  "uncertainty of the expansion coefficient, the misalignment and the drift were not stated")


@dataclass(frozen=True)
class Statement:
    """What the user states about a test (None: not stated): u_device_um (standard uncertainty of the device, um),
    temperature_deviation_K (from 20 degC), expansion_ppm_per_K (half-width of the machine's expansion coefficient's
    uncertainty), misalignment_mm (lateral walk of the beam over the measured length), drift_um (EVE, um)."""
    u_device_um: float | None = None
    temperature_deviation_K: float | None = None
    expansion_ppm_per_K: float | None = None
    misalignment_mm: float | None = None
    drift_um: float | None = None

    @property
    def empty(self) -> bool:
        return all(v is None for v in (self.u_device_um, self.temperature_deviation_K, self.expansion_ppm_per_K,
                                       self.misalignment_mm, self.drift_um))


def check(st: Statement) -> Statement:
    """InputError naming the key unless every stated value is a finite number (>= 0 but the temperature) and the
    temperature deviation and the expansion coefficient come together."""
    for key in ("u_device_um", "expansion_ppm_per_K", "misalignment_mm", "drift_um", "temperature_deviation_K"):
        v = getattr(st, key)
        if v is None:
            continue
        if not math.isfinite(v) or (key != "temperature_deviation_K" and v < 0):
            raise InputError(f"{key}: expected a finite number{'' if key == 'temperature_deviation_K' else ' >= 0'}, "
                             f"got {v}", key=key)
    if (st.temperature_deviation_K is None) != (st.expansion_ppm_per_K is None):
        raise InputError("temperature_deviation_K and expansion_ppm_per_K: state both (the expansion of the machine "
                         "over the temperature deviation is uncertain by the coefficient's uncertainty), or neither",
                         key=("temperature_deviation_K", "expansion_ppm_per_K"))
    return st


def budget(st: Statement, length_mm: float) -> dict | None:
    """The budget for a measured length (mm): standard uncertainties per contributor (um), U (k = 2) of E, M, B
    (um; B left out when nothing stated enters it), and the statement in words; None if nothing was stated."""
    check(st)
    if st.empty:
        return None
    L = float(length_mm)
    u = {}
    if st.u_device_um is not None:
        u["device"] = st.u_device_um
    if st.temperature_deviation_K is not None:
        u["expansion"] = (L / 1000.0) * abs(st.temperature_deviation_K) * st.expansion_ppm_per_K / math.sqrt(3)
    if st.misalignment_mm is not None and L > 0:
        u["misalignment"] = 1e3 * st.misalignment_mm ** 2 / (2 * L) / (2 * math.sqrt(3))
    if st.drift_um is not None:
        u["drift"] = st.drift_um / (2 * math.sqrt(3))
    ue = 2 * math.sqrt(sum(v ** 2 for v in u.values()))
    ub = 2 * u["drift"] if "drift" in u else None
    parts = ", ".join(f"{k} {v:.3g}" for k, v in u.items())
    text = (f"U (k = 2) after ISO 230-9's simplified budget over {L:g} mm: E and M {ue:.2f} um, B "
            + (f"{ub:.2f} um" if ub is not None else "none stated (the stated contributors cancel in a reversal; "
               "state the drift)") + f"; standard uncertainties (um): {parts}; R and A: no budget")
    U = {"E": ue, "M": ue, **({"B": ub} if ub is not None else {})}
    return {"U_um": U, "u_um": u, "k": 2, "length_mm": L,
            "inputs": {k: v for k, v in st.__dict__.items() if v is not None}, "statement": text}


def none_statement() -> dict:
    """The record when nothing was stated: no U, and why."""
    return {"U_um": {}, "statement": NONE_STATEMENT}
