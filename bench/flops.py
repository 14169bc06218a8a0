"""Floating-point operations per pose of the fast GSIL kernel, counted from the generated code, and the peak.

Counting method: walk the AST of the vectorised pass of `_gsil_block` (the loop that computes every pose) and
count one operation per arithmetic operator (+ - * /, augmented assignments included), per abs, sqrt and floor
call, and the operations of the inlined helpers `_sincos` and `_kink` at each call. Comparisons, selects, loads
and stores are not counted; the scalar pass over poses with a kink or near-cancelling errors is not counted
either (it runs on a minority of poses), so the count is a lower bound of the work per pose.
Run: .venv/bin/python bench/flops.py [--machine NAME]
"""
from __future__ import annotations

import argparse
import ast
import inspect
import os
import re

import fiveaxis
from fiveaxis.model.machine import MACHINES_DIR


class _Counter(ast.NodeVisitor):
    def __init__(self, helpers):
        self.n = 0
        self.helpers = helpers

    def visit_BinOp(self, node):
        if isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
            self.n += 1
        self.generic_visit(node)

    def visit_AugAssign(self, node):
        if isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
            self.n += 1
        self.generic_visit(node)

    def visit_Call(self, node):
        name = ast.unparse(node.func)
        if name in ("abs", "math.sqrt", "math.floor"):
            self.n += 1
        elif name in self.helpers:
            self.n += self.helpers[name]
        self.generic_visit(node)

    def visit_Subscript(self, node):   # index arithmetic is integer work
        self.visit(node.value)


def _function_ops(fn, helpers=None) -> int:
    tree = ast.parse(inspect.getsource(fn.py_func if hasattr(fn, "py_func") else fn).strip())
    c = _Counter(helpers or {})
    c.visit(tree.body[0])
    return c.n


def flops_per_pose(kernels) -> int:
    """Operations per pose of the vectorised pass of kernels._gsil_block (see the module docstring)."""
    helpers = {"_sincos": _function_ops(kernels._sincos), "_kink": _function_ops(kernels._kink)}
    src = inspect.getsource(kernels._gsil_block.py_func)
    tree = ast.parse(src.strip()).body[0]
    loops = [n for n in tree.body if isinstance(n, ast.For)]
    main = loops[1]                   # 0: copy poses (and libm beyond _TRIG_MAX); 1: the vectorised pass
    c = _Counter(helpers)
    for stmt in main.body:
        c.visit(stmt)
    return c.n


def cpu() -> dict:
    """CPU model, cores and clock (GHz) from /proc/cpuinfo, and the double-precision peak assumed (GFLOP/s):
    cores x GHz x 16 (AVX2: two 4-wide FMA units, 2 flops each); the AVX-512 figure is twice that."""
    text = open("/proc/cpuinfo").read() if os.path.exists("/proc/cpuinfo") else ""
    model = re.search(r"model name\s*:\s*(.*)", text)
    mhz = [float(x) for x in re.findall(r"cpu MHz\s*:\s*([\d.]+)", text)]
    cores = len(os.sched_getaffinity(0))
    ghz = (max(mhz) / 1000.0) if mhz else float("nan")
    flags = re.search(r"flags\s*:\s*(.*)", text)
    flags = set(flags.group(1).split()) if flags else set()
    return {"model": model.group(1).strip() if model else "unknown", "cores": cores, "ghz": ghz,
            "avx2_fma": {"avx2", "fma"} <= flags, "avx512f": "avx512f" in flags,
            "peak_gflops_avx2": cores * ghz * 16.0, "peak_gflops_avx512": cores * ghz * 32.0}


def main(argv=None) -> dict:
    """Print the count of every shipped machine's kernel (or of --machine) and the peak of this CPU."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machine", action="append", default=None, help="a shipped machine (default: all)")
    a = ap.parse_args(argv)
    names = a.machine or sorted(p.stem for p in MACHINES_DIR.glob("*.toml"))
    info = cpu()
    out = {"cpu": info, "flops_per_pose": {}}
    for name in names:
        k = fiveaxis.load(name).kernels
        if not hasattr(k, "_gsil_block"):
            continue
        out["flops_per_pose"][name] = flops_per_pose(k)
        print(f"{name}: {out['flops_per_pose'][name]} flops per pose (vectorised pass of _gsil_block)")
    print(f"CPU {info['model']}, {info['cores']} cores at {info['ghz']:.2f} GHz: peak {info['peak_gflops_avx2']:.1f}"
          f" GFLOP/s (AVX2 FMA), {info['peak_gflops_avx512']:.1f} (AVX-512)")
    return out


if __name__ == "__main__":
    main()
