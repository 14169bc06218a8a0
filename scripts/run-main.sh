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

# --- section: compensation (issue 10)
# From the identified model to the controller, and the error falls on the (simulated) machine: an A/C trunnion with
# hidden errors and two effects is measured, fitted, compensated (volumetric table + LinuxCNC files), and measured
# again with the table applied to its commands (same seed: the same machine, poses and noise).
CDIR=${FIVEAXIS_OUT:-out}/compensation   # (OUT is taken by the section above)
mkdir -p "$CDIR"
SIM=("$BIN/fiveaxis" simulate --machine ac_trunnion --effect dx_x:x2 --effect ex_x:x1 --n 1000 --noise 0.001 --seed 4)
say "Measure a simulated A/C trunnion (hidden errors, effects dx_x:x2 and ex_x:x1, 1 um noise): $CDIR/before.csv"
"${SIM[@]}" -o "$CDIR/before.csv" --force 2>&1 | tee "$CDIR/before.log"
say "Fit the model with those effects, save it: $CDIR/model.json"
FIT=$("$BIN/fiveaxis" fit "$CDIR/before.csv" --machine ac_trunnion --add dx_x:x2 --add ex_x:x1 \
      -o "$CDIR/model.json" --force)
echo "$FIT" | sed '/Parameters determined/,$d'
say "Compensate: the volumetric table, LinuxCNC's files, the predicted error (fiveaxis compensate)"
"$BIN/fiveaxis" compensate "$CDIR/model.json" -o "$CDIR/comp" --force --plot
say "Measure the same machine again with the table applied to its commands (simulate --compensation)"
"${SIM[@]}" -o "$CDIR/after.csv" --force --compensation "$CDIR/comp" 2>&1 | tee "$CDIR/after.log"
BEFORE=$(sed -n 's/.*deviation RMS \([0-9.e+-]*\) um.*/\1/p' "$CDIR/before.log")
RESID=$(echo "$FIT" | sed -n 's/.*residual RMS: *\([0-9.e+-]*\) um.*/\1/p')
AFTER=$(sed -n 's/.*deviation RMS \([0-9.e+-]*\) um.*/\1/p' "$CDIR/after.log")
say "Measured tool-tip error RMS before: $BEFORE um; the model's residual: $RESID um; measured after compensation: $AFTER um (1 um noise per axis: sqrt(3) um of it is noise)"
# --- end section: compensation
