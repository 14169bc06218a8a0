"""A simulated ISO 230-3 test: what the five sensors around a test mandrel and the temperature sensors of a machine
read over some hours, with a known truth (for the tests, and for users trying `fiveaxis iso230-3`).

The machine (a vertical machining centre, spindle along Z), time t in s, temperatures in degC:
- temp_spindle (housing): warm-up towards +RISE_SPINDLE K with TAU_WARM while the spindle runs, back with TAU_COOL
  when it stands (exact first-order exponentials: `fiveaxis.measurement.temperatures`' spindle channel);
- temp_air: a day's cycle (AIR_DAY K, 24 h) and the shop's air conditioning (AIR_HVAC K, period HVAC_PERIOD);
- temp_column: the column, lagging a mix of the spindle's heat and the air (TAU_COLUMN);
- temp_xscrew (moving-axis test): the X ball screw warming while X travels (RISE_SCREW K, TAU_SCREW).
The tool side relative to the table (the truth, um and urad):
    Z = -GZ * (spindle housing lagged by TAU_NOSE - its start)  - GZ_AIR * (column - its start)
    X = GX * (column - start),  Y = GY * (spindle lagged - start) + GY_AIR * (air lagged by TAU_COLUMN - start)
    A = GA * (column - start),   B = GB * (spindle lagged - start)
and, in the moving-axis test, the position error of X at a target P: ALPHA * (screw - start) * P (a scale
growing from the axis' zero). The sensors read X, Y, Z at the mandrel's free end, X2 = X + B l and Y2 = Y - A l
at the spacing l (mm) along +Z, each with its own noise (NOISE_UM) and rounded to RESOLUTION_UM; the temperatures
with TEMP_NOISE and rounded to TEMP_RESOLUTION (as `fiveaxis.measurement.temperatures.readings`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..measurement import temperatures as heat

RISE_SPINDLE, TAU_WARM, TAU_COOL = 12.0, 2400.0, 3000.0       # K, s, s
TAU_NOSE = 900.0                                               # s: the spindle nose lags the housing sensor
AIR_DAY, AIR_HVAC, HVAC_PERIOD = 0.8, 0.25, 2700.0             # K, K, s
TAU_COLUMN, COLUMN_SHARE = 7200.0, 0.25                        # s; share of the spindle's heat reaching the column
RISE_SCREW, TAU_SCREW = 4.0, 3600.0                            # K, s
GZ, GZ_AIR, GX, GY, GY_AIR = 1.8, 1.5, 1.2, 0.15, 2.0          # um/K
GA, GB = 4.0, 2.5                                              # urad/K
ALPHA = 11.5e-6                                                # 1/K: steel
NOISE_UM, RESOLUTION_UM = 0.1, 0.1
TEMP_NOISE, TEMP_RESOLUTION = 0.01, 0.01                       # degC
START_DEGC = {"temp_spindle": 21.0, "temp_air": 20.0, "temp_column": 20.5, "temp_xscrew": 20.8}


@dataclass
class ThermalSimulation:
    """The file's columns (as written: mm, degC, s, rpm) and the truth behind them (um, urad, degC, s)."""
    columns: dict
    truth: dict = field(default_factory=dict)

    def frame(self):
        import pandas as pd   # heavy: only where a file is written
        return pd.DataFrame(self.columns)


def _lag(t, x, tau):
    """x through a first-order lag of time constant tau (s), at rest at x[0]; exact for x linear between samples."""
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(t)):
        h = t[k] - t[k - 1]
        a = math.exp(-h / tau)
        b = (1 - a) * tau / h - a                  # weight of the ramp's start in the exact solution
        y[k] = a * y[k - 1] + b * x[k - 1] + (1 - a - b) * x[k]
    return y


def simulate(test: str = "spindle", hours: float = 6.0, interval_s: float = 60.0, run_hours: float = 4.0,
             speed_rpm: float = 8000.0, spacing_mm: float = 100.0, spindle_column: bool = True, seed: int = 0,
             air_shift_h: float = 9.0, targets_mm=(0.0, 400.0)) -> ThermalSimulation:
    """A simulated test (see the module docstring): test etve (the machine at rest), spindle (running at speed_rpm
    for run_hours from the start, then stopped) or axis (X travelling between targets_mm, read at each in turn,
    while the spindle stands); hours of readings every interval_s; the spindle's speed in a column spindle_rpm or
    (spindle_column=False) left to be stated; seed of the noise; air_shift_h: the time of day at the start (h)."""
    if test not in ("etve", "spindle", "axis"):
        raise InputError(f"test: unknown ISO 230-3 test {test!r} (expected etve, spindle or axis)")
    for key, v, lo, hi in (("test_hours", hours, 0.1, 200.0), ("interval_s", interval_s, 0.1, 3600.0),
                           ("spacing_mm", spacing_mm, 1.0, 2000.0), ("run_hours", run_hours, 0.0, 200.0),
                           ("speed_rpm", speed_rpm, 0.0, 2e5)):
        if not (math.isfinite(v) and lo <= v <= hi):
            raise InputError(f"{key}: expected a number from {lo:g} to {hi:g}, got {v:g}", key=key)
    if not (isinstance(seed, (int, np.integer)) and 0 <= seed < 2 ** 63):
        raise InputError(f"seed: expected a whole number >= 0, got {seed!r}")
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, hours * 3600.0 + 1e-9, interval_s)
    n = len(t)
    if n < 3:
        raise InputError(f"test_hours: {hours:g} h of readings every {interval_s:g} s are {n} readings (expected at "
                         f"least 3)", key="test_hours")
    on, off = (0.0, run_hours * 3600.0) if test == "spindle" else (math.inf, math.inf)
    sensor = {"noise": TEMP_NOISE, "resolution": TEMP_RESOLUTION}
    housing = heat.Channel("temp_spindle", "spindle", {
        "start": START_DEGC["temp_spindle"], "rise": RISE_SPINDLE, "tau": TAU_WARM, "cool": TAU_COOL, **sensor,
        "on": [on] if test == "spindle" else [], "off": [off] if test == "spindle" else []})
    spindle = heat.history([housing], t)["temp_spindle"]
    day = 2 * math.pi * (t / 3600.0 + air_shift_h - 9.0) / 24.0
    air = START_DEGC["temp_air"] + AIR_DAY * np.sin(day) + AIR_HVAC * np.sin(2 * math.pi * t / HVAC_PERIOD)
    column_drive = (START_DEGC["temp_column"] + COLUMN_SHARE * (spindle - spindle[0]) + (air - air[0]))
    column = _lag(t, column_drive, TAU_COLUMN)
    nose = _lag(t, spindle, TAU_NOSE)
    air_slow = _lag(t, air, TAU_COLUMN)
    dT = {"spindle": nose - nose[0], "column": column - column[0], "air": air_slow - air_slow[0]}
    truth = {"t_s": t,
             "X_um": GX * dT["column"],
             "Y_um": GY * dT["spindle"] + GY_AIR * dT["air"],
             "Z_um": -GZ * dT["spindle"] - GZ_AIR * dT["column"],
             "A_urad": GA * dT["column"],
             "B_urad": GB * dT["spindle"]}
    temps = {"temp_spindle": spindle, "temp_air": air, "temp_column": column}
    position = None
    if test == "axis":
        screw_rise = RISE_SCREW * -np.expm1(-t / TAU_SCREW)
        temps["temp_xscrew"] = START_DEGC["temp_xscrew"] + screw_rise
        position = np.asarray(targets_mm, float)[np.arange(n) % len(targets_mm)]
        truth["X_um"] = truth["X_um"] + 1e3 * ALPHA * screw_rise * position
        truth["position_mm"] = position
    truth.update(temps)

    def read(um):
        mm = 1e-3 * (um + rng.normal(0.0, NOISE_UM, n))
        step = 1e-3 * RESOLUTION_UM
        return np.round(np.round(mm / step) * step, 6)

    cols = {"t": t}
    if position is not None:
        cols["X"] = position
    cols["dx"] = read(truth["X_um"])
    cols["dy"] = read(truth["Y_um"])
    cols["dz"] = read(truth["Z_um"])
    cols["dx2"] = read(truth["X_um"] + 1e-3 * truth["B_urad"] * spacing_mm)
    cols["dy2"] = read(truth["Y_um"] - 1e-3 * truth["A_urad"] * spacing_mm)
    channels = [heat.Channel(name, "constant", {"start": float(T[0]), **sensor}) for name, T in temps.items()]
    for name, T in heat.readings(channels, temps, rng).items():
        cols[name] = np.round(T, 4)
    if test == "spindle" and spindle_column:
        cols["spindle_rpm"] = np.where((t >= on) & (t < off), speed_rpm, 0.0)
    truth.update({"test": test, "spacing_mm": spacing_mm, "spindle_on_min": on / 60.0 if test == "spindle" else None,
                  "spindle_off_min": off / 60.0 if test == "spindle" else None, "speed_rpm": speed_rpm,
                  "seed": seed})
    return ThermalSimulation(cols, truth)
