#!/usr/bin/env bash
# The main job of `make run`, step by step; each step is one fiveaxis command a user can run alone.
set -euo pipefail
BIN=${1:-.venv/bin}
echo
echo "== Table 2 of the paper's machine (equations convention), as JSON (first groups)"
"$BIN/fiveaxis" table2 --machine li2018 --json | head -n 20
