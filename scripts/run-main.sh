#!/usr/bin/env bash
# The main job of `make run`, step by step; each step is one fiveaxis command a user can run alone.
set -euo pipefail
BIN=${1:-.venv/bin}
say() { printf '\n== %s\n' "$*"; }

# --- section: derive (issue 2)
say "Table 2 of the paper's machine (equations convention, S_yz where Eq. 4 puts it), as LaTeX"
"$BIN/fiveaxis" table2 --machine li2018 --latex
# --- end section: derive

# --- section: sensitivity (issue 3, issue 14)
say "GSA of the paper's workspace (preset paper: Sect. 4.2, Fig. 14), printed-table convention; Fig. 16 at the nine points"
"$BIN/fiveaxis" gsa --machine li2018 --convention printed --preset paper --compensate
for cone in 1 2; do
  say "LSA of the 1/4 cone at machining position $cone (Sect. 4.1, Tables 3-4, Fig. 10); Fig. 11"
  "$BIN/fiveaxis" lsa --machine li2018 --convention printed --cone "$cone" --compensate
done
say "Sobol' total indices over the same workspace, against the GSIL ranking"
"$BIN/fiveaxis" sobol --machine li2018 --convention printed --preset paper --top 8
TOOLPATH=examples/ac_trunnion_sphere.ngc
say "A part program on another machine: LSA along $TOOLPATH (ac_trunnion, G-code read by LinuxCNC's rs274), halving its vital errors"
if [ -x /usr/bin/rs274 ]; then
  "$BIN/fiveaxis" lsa --machine ac_trunnion --toolpath "$TOOLPATH" --surface sphere:50,30,20 --compensate --top 6 --segments 6
else
  echo "skipped: /usr/bin/rs274 is missing (Debian: apt-get install linuxcnc-uspace)"
fi
# --- end section: sensitivity

# --- section: measurements (issue 4)
# Confront the model with measurements: diagnose, add the top candidate, diagnose again, until nothing is missing.
MEAS=examples/li2018_measurements.csv
say "Measurements ($MEAS: 1500 simulated poses with two hidden effects): fit of the 41 errors, identifiability"
"$BIN/fiveaxis" fit "$MEAS" | sed '/Not determined/,$d'
ADD=()
FOUND=()
TRAIL=""
for round in 1 2 3 4; do
    say "diagnose, round $round: fiveaxis diagnose $MEAS ${ADD[*]}"
    OUT=$("$BIN/fiveaxis" diagnose "$MEAS" "${ADD[@]}" --top 3)
    echo "$OUT"
    RMS=$(echo "$OUT" | sed -n 's/.*residual RMS \([0-9.e+-]*\) um against noise \([0-9.e+-]*\) um.*/\1/p')
    NOISE=$(echo "$OUT" | sed -n 's/.*residual RMS \([0-9.e+-]*\) um against noise \([0-9.e+-]*\) um.*/\2/p')
    TRAIL="$TRAIL${TRAIL:+ -> }$RMS um"
    NEXT=$(echo "$OUT" | sed -n 's/.*next: fiveaxis diagnose FILE --add \(.*\)$/\1/p')
    [ -n "$NEXT" ] || break
    ADD+=(--add "$NEXT")
    FOUND+=("$NEXT")
done
say "The error fell: residual RMS $TRAIL against noise $NOISE um; effects found: ${FOUND[*]:-none}"
# --- end section: measurements
