"""Progress bars (tqdm on stderr) for long runs, on a terminal and in logs.

On a terminal the bar redraws in place twice a second. When stderr is not a terminal (a log file, a batch job)
a long run still reports, one line at a time and at a modest rate (every LOG_INTERVAL seconds), so a log shows
that the run is alive and how far it got; a short run stays silent there.
"""
from __future__ import annotations

import sys

#: Seconds between two progress lines when stderr is not a terminal.
LOG_INTERVAL = 30.0


class _Lines:
    """A text stream for tqdm that turns its carriage-return redraws into whole lines (for logs)."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text):
        text = text.replace("\r", "").replace("\x1b[A", "")
        if text.strip():
            self.stream.write(text.rstrip("\n") + "\n")

    def flush(self):
        self.stream.flush()


def bar(total: int, enabled=None, desc: str = "", unit: str = "pose", long: bool = False, stream=None):
    """A tqdm bar over `total` items on stderr.

    enabled: True/False to force it on or off; None shows it on a terminal when `long`, and in logs (not a
    terminal) when `long`, one line every LOG_INTERVAL seconds. `long` says whether the caller expects the run
    to take a while (e.g. more than a few chunks of poses).
    """
    from tqdm import tqdm   # loaded only where a progress bar is shown
    stream = sys.stderr if stream is None else stream
    tty = hasattr(stream, "isatty") and stream.isatty()
    if enabled is None:
        enabled = bool(long)
    if tty:
        return tqdm(total=total, disable=not enabled, desc=desc, unit=unit, unit_scale=True, file=stream,
                    mininterval=0.5)
    return tqdm(total=total, disable=not enabled, desc=desc, unit=unit, unit_scale=True, file=_Lines(stream),
                mininterval=LOG_INTERVAL, maxinterval=LOG_INTERVAL, ncols=80, dynamic_ncols=False)
