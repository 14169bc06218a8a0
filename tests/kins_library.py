"""The core of a generated kinematics module (fiveaxis_kins.comp) as a plain shared library, called through ctypes:
the C between the `fiveaxis core` markers compiled with gcc (no LinuxCNC needed); and fitted-like models with
effects for the module's tests."""
from __future__ import annotations

import ctypes
import hashlib
import shutil
import subprocess
from pathlib import Path

import numpy as np

from fiveaxis.effects import families as fx
from fiveaxis.estimation import fitted_model as MF

#: Position-dependent effects of the test models (value at u = 1 or amplitude, mm or rad): a polynomial on a linear
#: axis, one on each rotary axis (a full-turn one is evaluated wrapped), a periodic effect, one on the tool length.
EFFECTS = {"ac_trunnion": [("dx_x:x2", 0.01), ("ex_x:x1", 2e-5), ("dx_C:C1", 0.008), ("ey_A:A3", 3e-5),
                           ("dy_y:yp50", (0.003, -0.002)), ("L:z1", 0.004)],
           "li2018": [("dx_x:x2", 0.01), ("ez_y:y1", 2e-5), ("dx_A:A2", 0.005), ("ex_B:Bp30", (1e-5, 2e-5)),
                      ("L:x1", 0.003)],
           "tilting_head": [("dz_z:z3", 0.01), ("ex_x:x1", 2e-5), ("dy_C:C1", 0.006), ("ez_B:B2", 2e-5),
                            ("dx_C:Cp90", (0.002, 0.001))]}


def fitted_like(model, seed=0) -> MF.FittedModel:
    """A fitted model as a fit writes it: random base errors (tens of um, tens of urad) and the effects above."""
    machine = model.machine
    rng = np.random.default_rng(seed)
    errors = {n: float(rng.normal(0, 3e-5 if machine.is_angular(n) else 0.02)) for n in model.errors}
    records = []
    for ident, value in EFFECTS[machine.name]:
        e = fx.parse(ident, machine, model.errors)
        records.append(e.record(value if isinstance(value, tuple) else (value,)))
    return MF.FittedModel(machine.name, str(machine.path), MF.sha256(machine.path), model.convention, errors,
                          {n: "rad" if machine.is_angular(n) else "mm" for n in model.errors}, (), {},
                          tuple(records), fx.scales(machine))


BEGIN = "/* ==== fiveaxis core begin"
END = "/* ==== fiveaxis core end ==== */"
PRELUDE = "#include <math.h>\n#define FA_API\n"


def core(comp_text: str) -> str:
    """The plain C99 core of a module source (no HAL)."""
    start = comp_text.index(BEGIN)
    return PRELUDE + comp_text[start:comp_text.index(END) + len(END)] + "\n"


def gcc_missing() -> str | None:
    return None if shutil.which("gcc") else "gcc is not installed (Debian: apt-get install gcc)"


class Library:
    """The compiled core of one module source, with NumPy wrappers (mm, rad)."""

    def __init__(self, comp_text: str, folder: Path):
        code = core(comp_text)
        tag = hashlib.sha256(code.encode()).hexdigest()[:12]
        src = Path(folder) / f"fa_{tag}.c"
        so = Path(folder) / f"fa_{tag}.so"
        if not so.exists():
            src.write_text(code)
            subprocess.run(["gcc", "-std=gnu99", "-O2", "-Wall", "-Werror", "-fPIC", "-shared", str(src), "-o",
                            str(so), "-lm"], check=True, capture_output=True, text=True)
        self.lib = ctypes.CDLL(str(so))
        lib = self.lib
        d, i, p = ctypes.c_double, ctypes.c_int, ctypes.c_void_p
        lib.fa_values_size.restype = ctypes.c_ulong
        lib.fa_set_error.argtypes = [p, i, d]
        lib.fa_set_tool.argtypes = [p, d, d]
        lib.fa_set_slot.argtypes = [p, i, i, i, i, i, d, d, d, d, d]
        lib.fa_forward.argtypes = [p, p, d, p]
        lib.fa_tool.argtypes = [p, p, d, p, p]
        lib.fa_inverse.argtypes = [p, p, d, p, p]
        lib.fa_inverse.restype = i
        lib.fa_set_thermal.argtypes = [p, i, i, d, d]
        lib.fa_set_temp.argtypes = [p, i, d]
        lib.fa_temperatures.argtypes = [p, p, d]
        lib.fa_temperatures.restype = i
        lib.fa_slot_temperature.argtypes = [p, i]
        lib.fa_slot_temperature.restype = d
        lib.fa_lags_size.restype = ctypes.c_ulong
        self.values = ctypes.create_string_buffer(lib.fa_values_size())
        self.lags = ctypes.create_string_buffer(lib.fa_lags_size())
        lib.fa_defaults(self.values)
        lib.fa_lags_reset(self.lags)

    def set(self, values) -> None:
        """The pins' values of a linuxcnc.kinematics.ModuleValues."""
        from fiveaxis.linuxcnc.kinematics import KINDS
        lib = self.lib
        lib.fa_defaults(self.values)
        for k, e in enumerate(values.errors):
            lib.fa_set_error(self.values, k, float(e))
        lib.fa_set_tool(self.values, float(values.tool_length), float(values.damping))
        for k, s in enumerate(values.slots):
            lib.fa_set_slot(self.values, k, s.param, KINDS[s.kind], s.joint, s.degree, s.period, s.centre, s.half,
                            s.c0, s.c1)
            if s.channel >= 0:
                lib.fa_set_thermal(self.values, k, s.channel, s.reference, s.lag)
        lib.fa_lags_reset(self.lags)
        self.temperatures(values.references, 0.0)         # the sensors at their references, the lags at rest

    def temperatures(self, readings, dt: float) -> int:
        """The sensors' readings (degC, in pin order) after dt s: the temperature slots advanced; 1 on a fault."""
        for c, T in enumerate(readings):
            self.lib.fa_set_temp(self.values, c, float(T))
        return self.lib.fa_temperatures(self.values, self.lags, float(dt))

    def slot_temperature(self, k: int) -> float:
        return self.lib.fa_slot_temperature(self.values, k)

    def forward(self, joints, L) -> np.ndarray:
        q = np.ascontiguousarray(np.atleast_2d(joints), dtype=float)
        Ls = np.broadcast_to(np.asarray(L, float), (len(q),))
        out = np.zeros((len(q), 5))
        for k in range(len(q)):
            w = np.zeros(5)
            self.lib.fa_forward(self.values, q[k].ctypes.data, float(Ls[k]), w.ctypes.data)
            out[k] = w
        return out

    def tool(self, joints, L):
        q = np.ascontiguousarray(np.atleast_2d(joints), dtype=float)
        Ls = np.broadcast_to(np.asarray(L, float), (len(q),))
        P, V = np.zeros((len(q), 3)), np.zeros((len(q), 3))
        for k in range(len(q)):
            p, a = np.zeros(3), np.zeros(3)
            self.lib.fa_tool(self.values, q[k].ctypes.data, float(Ls[k]), p.ctypes.data, a.ctypes.data)
            P[k], V[k] = p, a
        return P, V

    def inverse(self, world, L):
        """(joints (n, 5), iterations (n,), converged (n,))"""
        w = np.ascontiguousarray(np.atleast_2d(world), dtype=float)
        Ls = np.broadcast_to(np.asarray(L, float), (len(w),))
        q = np.zeros((len(w), 5))
        its = np.zeros(len(w), dtype=int)
        ok = np.zeros(len(w), dtype=bool)
        for k in range(len(w)):
            out = np.zeros(5)
            it = ctypes.c_int(0)
            rc = self.lib.fa_inverse(self.values, w[k].ctypes.data, float(Ls[k]), out.ctypes.data,
                                     ctypes.byref(it))
            q[k], its[k], ok[k] = out, it.value, rc == 0
        return q, its, ok
