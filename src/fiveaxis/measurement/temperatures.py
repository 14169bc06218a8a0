"""Temperature histories for simulated measurements: what a machine's sensors read over a test (degC over t in s).

A channel is `KIND[:key=value,...]` (`simulate --temperature NAME=...`), all keys optional:

    spindle   warm-up while the spindle runs, cool-down when it stands: from `start`, towards start + rise with
              the time constant tau while running (runs from `on` to `off`, several as on=0/10800,off=7200/14400),
              back towards start with `cool` (default tau) when standing.
              start=20 rise=15 tau=900 on=0 off=7200 cool=tau
    air       a day's air cycle: start + amp sin(2 pi (t + shift) / period).   start=20 amp=1.5 period=86400 shift=0
    bed       a slow casting: start + rise (1 - exp(-(t - on) / tau)) from `on`.   start=20 rise=2 tau=14400 on=0
    mix       a sensor reading a mix of other channels: start + sum w (T_channel - its start), e.g. mix:spindle=0.3,
              air=1 (channels named without temp_; defined before it).   start=20
    constant  start.   start=20

and for every kind: noise (degC, standard deviation of each reading; default 0.02) and resolution (degC, the
sensor's step; default 0.01: readings rounded to it). `history` gives the true temperatures (what drives the
simulated machine); `readings` what the sensors read.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..model.columns import TEMPERATURE_PREFIX, TEMPERATURE_RANGE_DEGC, TEMPERATURE_RE

#: The keys of each kind and their defaults (degC, s).
KINDS = {
    "spindle": {"start": 20.0, "rise": 15.0, "tau": 900.0, "on": "0", "off": "7200", "cool": None},
    "air": {"start": 20.0, "amp": 1.5, "period": 86400.0, "shift": 0.0},
    "bed": {"start": 20.0, "rise": 2.0, "tau": 14400.0, "on": 0.0},
    "mix": {"start": 20.0},
    "constant": {"start": 20.0},
}
#: Keys every kind has: the sensor's noise (degC) and resolution (degC).
SENSOR = {"noise": 0.02, "resolution": 0.01}


@dataclass
class Channel:
    """One simulated sensor: its kind, its keys (degC, s) and, for a mix, the weights of other channels."""
    name: str                  # temp_<name>
    kind: str
    keys: dict
    weights: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"kind": self.kind, **self.keys, **({"weights": self.weights} if self.weights else {})}


def parse(name: str, spec: str) -> Channel:
    """A channel from `KIND[:key=value,...]`; InputError naming the key otherwise."""
    column = name if name.startswith(TEMPERATURE_PREFIX) else TEMPERATURE_PREFIX + name
    if not re.fullmatch(TEMPERATURE_RE, column):
        raise InputError(f"temperature {name!r}: expected a name of lower-case letters, digits and _ (e.g. spindle: "
                         f"the column temp_spindle)")
    kind, _, rest = spec.partition(":")
    if kind not in KINDS:
        raise InputError(f"temperature {name}={spec}: unknown kind {kind!r} (expected one of: {', '.join(KINDS)})")
    keys = {**KINDS[kind], **SENSOR}
    weights = {}
    for part in filter(None, rest.split(",")):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep:
            raise InputError(f"temperature {name}={spec}: expected key=value, got {part!r}")
        if kind == "mix" and key not in keys:
            weights[TEMPERATURE_PREFIX + key if not key.startswith(TEMPERATURE_PREFIX) else key] = _number(
                name, spec, key, value)
            continue
        if key not in keys:
            raise InputError(f"temperature {name}={spec}: unknown key {key!r} for {kind} (expected one of: "
                             f"{', '.join(keys)})")
        keys[key] = value.strip() if key in ("on", "off") else _number(name, spec, key, value)
    if kind == "spindle":
        keys["on"], keys["off"] = (_times(name, spec, k, keys[k]) for k in ("on", "off"))
        if len(keys["on"]) != len(keys["off"]) or any(b <= a for a, b in zip(keys["on"], keys["off"])):
            raise InputError(f"temperature {name}={spec}: expected as many on as off times, each off after its on "
                             f"(s), e.g. on=0/10800,off=7200/14400")
        keys["cool"] = keys["tau"] if keys["cool"] is None else keys["cool"]
    for key in ("tau", "period", "cool"):
        if key in keys and not keys[key] > 0:
            raise InputError(f"temperature {name}={spec}: key {key}: expected a positive time in s")
    for key in ("noise", "resolution"):
        if keys[key] < 0:
            raise InputError(f"temperature {name}={spec}: key {key}: expected a value >= 0 degC")
    return Channel(column, kind, keys, weights)


def _number(name, spec, key, value) -> float:
    try:
        x = float(value)
    except ValueError:
        raise InputError(f"temperature {name}={spec}: key {key}: expected a number, got {value!r}") from None
    if not math.isfinite(x):
        raise InputError(f"temperature {name}={spec}: key {key}: expected a finite number, got {value!r}")
    return x


def _times(name, spec, key, value) -> list[float]:
    if isinstance(value, list):
        return value
    return [_number(name, spec, key, v) for v in str(value).split("/") if v.strip()]


def history(channels, t) -> dict:
    """The true temperature of every channel (degC) at times t (s), in the order given (a mix reads earlier ones)."""
    t = np.asarray(t, float)
    out = {}
    for ch in channels:
        k = ch.keys
        if ch.kind == "spindle":
            T = k["start"] + k["rise"] * _running(t, k["on"], k["off"], k["tau"], k["cool"])
        elif ch.kind == "air":
            T = k["start"] + k["amp"] * np.sin(2 * math.pi * (t + k["shift"]) / k["period"])
        elif ch.kind == "bed":
            T = k["start"] + k["rise"] * -np.expm1(-np.clip(t - k["on"], 0, None) / k["tau"])
        elif ch.kind == "mix":
            T = np.full(len(t), k["start"])
            for other, w in ch.weights.items():
                if other not in out:
                    raise InputError(f"temperature {ch.name}: mixes {other}, which is not defined before it")
                src = next(c for c in channels if c.name == other)
                T = T + w * (out[other] - src.keys["start"])
        else:
            T = np.full(len(t), k["start"])
        lo, hi = TEMPERATURE_RANGE_DEGC
        if len(T) and (T.min() < lo or T.max() > hi):
            raise InputError(f"temperature {ch.name}: the history leaves {lo:g} to {hi:g} degC ({T.min():.4g} to "
                             f"{T.max():.4g}): not a machine's temperature")
        out[ch.name] = T
    return out


def _running(t, on, off, tau, cool) -> np.ndarray:
    """The share s (0..1) of the warm state: tau s' = 1 - s while running (on_k <= t < off_k), cool s' = -s else;
    s = 0 before the first run (exact piecewise)."""
    edges = sorted({0.0, *on, *off, float(np.max(t)) if len(t) else 0.0})
    s = 0.0
    running = lambda x: any(a <= x < b for a, b in zip(on, off))  # noqa: E731
    out = np.zeros(len(t))
    for a, b in zip(edges[:-1], edges[1:]):
        inside = (t >= a) & (t < b) if b != edges[-1] else (t >= a) & (t <= b)
        if running(a):
            out[inside] = 1.0 - (1.0 - s) * np.exp(-(t[inside] - a) / tau)
            s = 1.0 - (1.0 - s) * math.exp(-(b - a) / tau)
        else:
            out[inside] = s * np.exp(-(t[inside] - a) / cool)
            s = s * math.exp(-(b - a) / cool)
    return out


def readings(channels, true: dict, rng) -> dict:
    """What the sensors read: the true temperatures plus noise, rounded to their resolution (degC)."""
    out = {}
    for ch in channels:
        T = true[ch.name] + rng.normal(0.0, 1.0, len(true[ch.name])) * ch.keys["noise"]
        res = ch.keys["resolution"]
        out[ch.name] = np.round(T / res) * res if res > 0 else T
    return out
