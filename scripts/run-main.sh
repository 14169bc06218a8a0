#!/usr/bin/env bash
# The main job of `make run`, step by step; each step is one fiveaxis command a user can run alone.
set -euo pipefail
BIN=${1:-.venv/bin}
say() { printf '\n== %s\n' "$*"; }

# --- section: derive (issue 2)
say "Table 2 of the paper's machine (equations convention, S_yz where Eq. 4 puts it), as LaTeX"
"$BIN/fiveaxis" table2 --machine li2018 --latex
# --- end section: derive

# --- section: sensitivity (issue 3)
# --- end section: sensitivity

# --- section: measurements (issue 4)
# --- end section: measurements
