"""Benchmark: what the per-position profile candidates (`fiveaxis.diagnosis.profiles`) cost `diagnose`: the same
diagnosis with and without them, in the same run (`candidates.profile_candidates`, which `build_pool` calls, swapped
for an empty list), on the data
of bench_diagnose.py (li2018, 1,500 random poses with times and approach directions: every family searched, 30
profiles of 17 knots offered) and on an ISO 230-2 log (ac_trunnion, X, 9 targets, 5 cycles: 1 profile offered).
Run: .venv/bin/python bench/bench_profiles.py [--poses N] [--repeat R]   (the smoke test: --poses 200 --repeat 1)
"""
from __future__ import annotations

import argparse
import os
import sys

import fiveaxis
from fiveaxis.diagnosis import candidates as cd
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.measurement.simulate import simulate

sys.path.insert(0, os.path.dirname(__file__))
from bench_diagnose import _best  # noqa: E402  (the same best-of-3 timer)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=1500, help="poses of the li2018 case")
    ap.add_argument("--repeat", type=int, default=3, help="timed repeats (the best is kept)")
    a = ap.parse_args(argv)
    cases = {
        f"li2018 tip, {a.poses} poses": (fiveaxis.load("li2018"), dict(effects=["ex_x:x1=2e-5"], n=a.poses, seed=1,
                                                                options={"directions": True})),
        "ac_trunnion laser X, 9 targets": (fiveaxis.load("ac_trunnion"), dict(
            effects=["dx_x:xr=0.0125", "dx_x:x2=0.01"], n=100, seed=3, instrument="interferometer",
            options={"targets": 9, "axes": ["X"]})),
    }
    out = {}
    original = cd.profile_candidates
    for name, (model, kw) in cases.items():
        meas = simulate(model, kw.pop("effects"), noise=1e-3, **kw).meas
        D.diagnose(model, meas)                                        # warm up
        t_with, dg = _best(lambda: D.diagnose(model, meas), a.repeat)
        try:
            cd.profile_candidates = lambda *args, **kw: []
            t_without, _ = _best(lambda: D.diagnose(model, meas), a.repeat)
        finally:
            cd.profile_candidates = original
        offered = dg.decision["families"].get("profile", {}).get("M", 0)
        out[name] = {"with_s": t_with, "without_s": t_without, "ratio": t_with / t_without, "profiles": offered}
        print(f"{name}: diagnose {t_with:.2f} s with the profile candidates ({offered} offered), {t_without:.2f} s "
              f"without them: x{t_with / t_without:.2f} (best of {a.repeat})")
    return out


if __name__ == "__main__":
    main()
