"""Profile one `fiveaxis` command as the command line runs it (numba's workqueue layer, the pass's threads): every
PERIOD seconds the process's resident set size and every thread's innermost frames of the package, sampled by a
thread of its own (cProfile sees the main thread only; the row-block passes run on others). Prints the peak RSS
and where each thread was then, the RSS over time, and the samples per innermost frame and per two outer frames
(x PERIOD: seconds of a thread, the threads added).

Run: .venv/bin/python bench/sample_run.py [--period 0.25] [--out FILE] -- diagnose big.parquet --machine li2018 --json
(the smoke test: a tiny simulate). Used for the 10^6-pose profile of docs/performance.md.
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import io
import os
import sys
import threading
import time
import traceback


def _where(frame, depth: int = 4) -> str:
    """The innermost `depth` frames of the package in a thread's stack, innermost first."""
    own = [f"{os.path.basename(f.filename)}:{f.lineno}:{f.name}" for f in traceback.extract_stack(frame)
           if f"{os.sep}fiveaxis{os.sep}" in f.filename]
    return " < ".join(reversed(own[-depth:]))


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def sample(argv: list[str], period: float = 0.25) -> dict:
    """Run `fiveaxis argv` in this process, sampled: {rc, wall_s, samples: [(t s, rss MB, {thread: where})]}."""
    os.environ.setdefault("NUMBA_THREADING_LAYER", "workqueue")      # the command line's (fiveaxis.cli)
    from fiveaxis import cli
    samples, done = [], threading.Event()

    def run():
        me = threading.get_ident()
        while not done.is_set():
            frames = {tid: _where(f) for tid, f in sys._current_frames().items() if tid != me}
            samples.append((time.perf_counter(), _rss_mb(), frames))
            done.wait(period)

    th = threading.Thread(target=run, daemon=True)
    t0 = time.perf_counter()
    th.start()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = cli.main(list(argv))
    done.set()
    th.join()
    return {"rc": rc, "wall_s": time.perf_counter() - t0,
            "samples": [(t - t0, rss, fr) for t, rss, fr in samples], "stdout": out.getvalue()}


def report(rec: dict, period: float) -> str:
    s = rec["samples"]
    lines = [f"wall {rec['wall_s']:.1f} s, exit {rec['rc']}, {len(s)} samples"]
    if not s:
        return "\n".join(lines)
    t, rss, frames = max(s, key=lambda x: x[1])
    lines.append(f"peak RSS {rss:.0f} MB at {t:.1f} s; the threads then:")
    lines += [f"  {w}" for w in frames.values() if w]
    lines.append("RSS over time (every 5 s; the main thread's frames):")
    last = -1e9
    for t, rss, frames in s:
        if t - last >= 5:
            last = t
            lines.append(f"  {t:7.1f} s {rss:7.0f} MB  {next((w for w in frames.values() if w), '')}")
    for title, key in (("innermost frame", lambda w: w.split(" < ")[0]),
                       ("two outer frames", lambda w: " < ".join(w.split(" < ")[-2:]))):
        cnt = collections.Counter(key(w) for _, _, fr in s for w in fr.values() if w)
        lines.append(f"samples per {title} (x {period} s of a thread):")
        lines += [f"  {v:6d}  {k}" for k, v in cnt.most_common(25)]
    return "\n".join(lines)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--period", type=float, default=0.25, help="seconds between samples")
    ap.add_argument("--out", default=None, help="write the report here too")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the fiveaxis command and its arguments")
    a = ap.parse_args(argv)
    command = a.command[1:] if a.command[:1] == ["--"] else a.command
    rec = sample(command, a.period)
    text = report(rec, a.period)
    print(text)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(text + "\n")
    rec["report"] = text
    return rec


if __name__ == "__main__":
    main()
