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
say "GSA of the paper's workspace (Sect. 4.2, Fig. 14), printed-table convention; Fig. 16 at the nine points"
"$BIN/fiveaxis" gsa --machine li2018 --convention printed --compensate
for cone in 1 2; do
  say "LSA of the 1/4 cone at machining position $cone (Sect. 4.1, Tables 3-4, Fig. 10); Fig. 11"
  "$BIN/fiveaxis" lsa --machine li2018 --convention printed --cone "$cone" --compensate
done
say "Sobol' total indices over the same workspace, against the GSIL ranking"
"$BIN/fiveaxis" sobol --machine li2018 --convention printed --top 8
# --- end section: sensitivity

# --- section: measurements (issues 4, 8)
# Confront the model with measurements: diagnose, add the top candidate, diagnose again, until the verdict is no
# longer "missing effect" ("no missing effect", or "unexplained structure": then the template of a custom effect).
# loop FILE MACHINE [options...]: the rounds, reading `diagnose --json`; prints the RMS trail and the verdict.
loop() {
    local file=$1 machine=$2; shift 2
    local add=() found=() trail="" noise="" rms="" next="" verdict=""
    for round in 1 2 3 4; do
        say "diagnose, round $round: fiveaxis diagnose $file --machine $machine $* ${add[*]}"
        "$BIN/fiveaxis" diagnose "$file" --machine "$machine" "$@" "${add[@]}" --top 3
        IFS=$'\t' read -r rms noise next verdict < <("$BIN/fiveaxis" diagnose "$file" --machine "$machine" "$@" \
            "${add[@]}" --json | "$BIN/python" -c 'import json, sys; j = json.load(sys.stdin); c = j["candidates"]
print("%.4g\t%.4g\t%s\t%s" % (j["rms_mm_without_outliers"] * 1000, j["noise_mm"] * 1000,
      c[0]["id"] if j["verdict"] == "missing effect" and c else "-", j["verdict"]))')
        trail="$trail${trail:+ -> }$rms um"
        [ "$next" != "-" ] || break
        add+=(--add "$next")
        found+=("$next")
    done
    say "The error fell: residual RMS $trail against noise $noise um; effects found: ${found[*]:-none}; verdict: $verdict"
}

MEAS=examples/li2018_measurements.csv
say "Measurements ($MEAS: 1500 simulated poses with two hidden effects): fit of the 41 errors, identifiability"
"$BIN/fiveaxis" fit "$MEAS" | sed '/Not determined/,$d'
loop "$MEAS" li2018

OUT=${OUT:-out}
mkdir -p "$OUT"
RTEST="$OUT/ac_trunnion_rtest.csv"
say "An R-test on the A/C trunnion machine (3 sphere placements, unknown): simulated with a hidden radial motion of C"
"$BIN/fiveaxis" simulate --machine ac_trunnion --instrument rtest --n 600 --effect dx_C:C1=0.01 --seed 2 \
    --with-sigma -o "$RTEST" --force
"$BIN/fiveaxis" fit "$RTEST" --machine ac_trunnion | sed '/Combinations determined/,$d'
loop "$RTEST" ac_trunnion
BALLBAR="$OUT/li2018_ballbar.csv"
say "A ballbar test (ISO 230-4 circles, both directions) on li2018 with a hidden 6 um backlash of X"
"$BIN/fiveaxis" simulate --machine li2018 --instrument ballbar --n 600 --effect dx_x:xr=0.003 --seed 3 \
    -o "$BALLBAR" --force
loop "$BALLBAR" li2018
# --- end section: measurements
