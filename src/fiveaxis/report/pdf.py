"""Print the HTML report to PDF with headless Chromium (Debian package `chromium`), nothing fetched.

Chromium runs with a fresh profile in a temporary folder, no sandbox when we are root (it refuses otherwise),
and without its background network traffic (update checks, sync), which a closed network would refuse.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from ..exceptions import InputError
from ..outputs import write_bytes

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = ("--headless", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--no-first-run", "--no-default-browser-check", "--disable-extensions",
         "--mute-audio", "--no-pdf-header-footer")
TIMEOUT_S = 120


def browser() -> str | None:
    """Path of a Chromium executable (FIVEAXIS_CHROMIUM, else the first of CANDIDATES on PATH), or None."""
    env = os.environ.get("FIVEAXIS_CHROMIUM")
    if env:
        return env if Path(env).exists() else None
    return next((p for p in map(shutil.which, CANDIDATES) if p), None)


def args(exe: str, profile: Path) -> list[str]:
    """Command-line of a headless Chromium with a fresh profile (no sandbox as root)."""
    out = [exe, *FLAGS, f"--user-data-dir={profile}"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        out.append("--no-sandbox")
    return out


def print_pdf(html_path, pdf_path, force: bool = False) -> Path:
    """Print an HTML file to a PDF file (A4, the page's print style); atomically, never overwriting unless force."""
    exe = browser()
    if exe is None:
        raise InputError("PDF: no Chromium found (install the Debian package chromium, or set FIVEAXIS_CHROMIUM "
                         "to a Chromium executable)")
    html_path = Path(html_path).resolve()
    pdf_path = Path(pdf_path)
    with tempfile.TemporaryDirectory(prefix="fiveaxis-pdf-") as tmp:
        out = Path(tmp) / "report.pdf"
        cmd = args(exe, Path(tmp) / "profile") + [f"--print-to-pdf={out}", html_path.as_uri()]
        try:
            res = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise InputError(f"PDF: {exe} did not finish within {TIMEOUT_S} s") from None
        if not out.exists() or not out.read_bytes().startswith(b"%PDF"):
            tail = (res.stderr.strip().splitlines() or ["no output"])[-1]
            raise InputError(f"PDF: {exe} wrote no PDF (exit {res.returncode}: {tail})")
        write_bytes(pdf_path, out.read_bytes(), force=force)
        return Path(pdf_path)
