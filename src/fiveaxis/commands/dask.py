"""`fiveaxis dask`: GSIL of a workspace grid on Dask, on local worker processes or on a cluster (--scheduler)."""
from __future__ import annotations

import json
import os

from . import options
from ..exceptions import InputError
from .sensitivity import GSA_MAX_POSES as MAX_POSES, _count


def register_dask(p):
    options.machine(p)
    options.convention(p)
    p.add_argument("--preset", choices=("paper",), default=None,
                   help="a named workspace instead of the machine's (as `fiveaxis gsa --preset`)")
    p.add_argument("--axis", action="append", default=[], metavar="NAME=LO:HI:COUNT",
                   help="grid of one axis (mm; degrees for rotary axes), or NAME=VALUE to fix it; repeatable "
                        "(default: as `fiveaxis gsa`)")
    p.add_argument("--max-poses", type=_count, default=MAX_POSES, metavar="N",
                   help=f"refuse a grid of more than N poses (after the reduction) before starting (default "
                        f"{MAX_POSES:.0e})")
    p.add_argument("--l0", type=float, default=None, help="tool length L0, mm (default: the machine file's)")
    p.add_argument("--le", type=float, default=None, help="effective cutting length LE, mm (default: the file's)")
    p.add_argument("--errors", action="append", default=[], metavar="FILE|NAME=VALUE",
                   help="error values (mm, rad), as for `fiveaxis gsa`")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:8786",
                   help="address of a running dask scheduler; default: a local cluster of --workers processes")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="local worker processes, one thread each (default: the number of CPUs)")
    p.add_argument("--chunk", type=int, default=None, help="poses per task (default 2**20)")
    p.add_argument("--worker-kernel", default="serial", choices=("serial", "parallel"),
                   help="serial nogil kernel (safe with threaded workers; default) or the parallel kernel "
                        "(only for workers with one thread each)")
    p.add_argument("--no-reduce", dest="reduce", action="store_false",
                   help="evaluate every grid pose, also along axes that appear in no J (X for li2018)")
    bar = p.add_mutually_exclusive_group()
    bar.add_argument("--progress", action="store_true", default=None, help="always show the progress bar")
    bar.add_argument("--no-progress", dest="progress", action="store_false", help="never show the progress bar")
    options.json_output(p, "print {indices, ranking, settings} as JSON")
    p.add_argument("--top", type=int, default=10, help="rows of the printed ranking (default 10)")
    p.set_defaults(func=run_dask)


def run_dask(args) -> int:
    from .. import parallel
    from ..sensitivity import distributed
    from ..model.error_values import read
    from ..guards import check_size
    from ..model.error_model import load
    from ..sensitivity.indices import reduce_grid
    from ..report import sensitivity_text as S
    from .sensitivity import _grid, _iso
    if args.scheduler is not None:
        try:
            parallel.scheduler_address(args.scheduler)     # before the model loads: a typo fails at once
        except InputError as exc:
            raise InputError(f"--scheduler: {exc}") from None
    model = load(args.machine, args.convention)
    errors = read(model, args.errors).values
    grid, source, L0, LE = _grid(args, model)
    args.l0 = L0 if args.l0 is None else args.l0
    args.le = LE if args.le is None else args.le
    for a in grid.axes:
        check_size(a.count, f"points on axis {a.name}", args.max_poses, "--max-poses {n}")
    work = reduce_grid(model, grid)[0] if args.reduce else grid
    check_size(work.size, "poses", args.max_poses, "--max-poses {n}")
    if args.chunk is not None and args.chunk < 1:
        raise InputError(f"--chunk: expected a positive number of poses, got {args.chunk}")
    if args.workers < 1:
        raise InputError(f"--workers: expected a positive number of worker processes, got {args.workers}")
    distributed.warm(model)          # compile or load the cache here, before any local worker starts
    cluster = None
    if args.scheduler is not None:
        try:
            client = parallel.connect(args.scheduler)
        except InputError as exc:
            raise InputError(f"--scheduler: {exc}") from None
    else:
        cluster, client = parallel.local_cluster(args.workers, 1)
    try:
        res = distributed.gsil(model, grid, client, errors, args.l0, args.le,
                               chunk=distributed.CHUNK if args.chunk is None else args.chunk, reduce=args.reduce,
                               worker_kernel=args.worker_kernel, progress=args.progress)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    res.settings["workspace"] = source
    if args.json:
        print(json.dumps(res.to_json(), indent=1))
        return 0
    out = res.to_json()
    print("\n".join(S.ranking(out, _iso(model), args.top, "GSIL proportions PG_i (Eq. 14, 16), largest first")
                    + S.settings(out["settings"]) + S.dask(out["settings"])))
    return 0
