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

# --- section: measurements (issues 4, 8)
# Confront the model with measurements: the calibration loop (fiveaxis.diagnosis.rounds, as `fiveaxis report` runs
# it): diagnose, add the top candidate, diagnose again, until the verdict is no longer "missing effect" ("no missing
# effect", or "unexplained structure": then the template of a custom effect); then the RMS trail and the verdict.
# loop FILE MACHINE [options...]
loop() {
    local file=$1 machine=$2; shift 2
    say "The calibration loop: fiveaxis diagnose $file --machine $machine $* --rounds 4 --top 3"
    "$BIN/fiveaxis" diagnose "$file" --machine "$machine" "$@" --rounds 4 --top 3
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

# --- section: iso230 (issue 22)
# The figures a laser's and a ballbar's software print first, from the same files fiveaxis fits; and a lead-screw
# error table (a per-position profile) found, fitted and put into LinuxCNC's compensation file.
IDIR=${OUT:-out}/iso230
mkdir -p "$IDIR"
LASER="$IDIR/ac_trunnion_laser_x.csv"
PROFILE="0,0.012,-0.008,0.015,-0.004,0.003,-0.015,0.009,-0.005"
LSIM=("$BIN/fiveaxis" simulate --machine ac_trunnion --instrument interferometer --axes X --targets 9
      --effect "dx_x:xkT9=$PROFILE" --effect dx_x:xr=0.0125 --seed 3)
say "An ISO 230-2 laser run of X on the A/C trunnion (9 irregular targets, 5 cycles; a lead-screw error of 30 um spread at the targets, a 25 um reversal): $LASER"
"${LSIM[@]}" -o "$LASER" --force
say "ISO 230-2: fiveaxis iso230-2 $LASER (with ISO 230-9's uncertainty from what the test states)"
"$BIN/fiveaxis" iso230-2 "$LASER" --machine ac_trunnion --u-device 0.4 --temperature-deviation 0.5 \
    --expansion-ppm-per-K 2 --misalignment 0.5 --drift 0.2 --plot "$IDIR"
say "diagnose with the reversal in: the per-position profile at the 9 measured targets, dx_x:xkT9, is offered"
"$BIN/fiveaxis" diagnose "$LASER" --machine ac_trunnion --add dx_x:xr --top 2
say "Fit the reversal and the profile, compensate: LinuxCNC's trims at the profile's knots, the targets (joint0-X.comp)"
"$BIN/fiveaxis" fit "$LASER" --machine ac_trunnion --add dx_x:xr --add dx_x:xkT9 -o "$IDIR/model.json" --force \
    | sed -n '/residual RMS/p'
# the volumetric table gets a node at each of the profile's 9 knots by default (compensate sizes it to the
# profiles); it cannot hold the reversal, and says that the comp files do
"$BIN/fiveaxis" compensate "$IDIR/model.json" -o "$IDIR/comp" --poses 500 --force > "$IDIR/compensate.txt"
grep "warning:" "$IDIR/compensate.txt" || true
cat "$IDIR/comp/linuxcnc/joint0-X.comp"
say "The same laser run with LinuxCNC's files applied (simulate --compensation --linuxcnc): ISO 230-2 again"
"${LSIM[@]}" -o "$IDIR/ac_trunnion_laser_x_after.csv" --force --compensation "$IDIR/comp" --linuxcnc
"$BIN/fiveaxis" iso230-2 "$IDIR/ac_trunnion_laser_x_after.csv" --machine ac_trunnion | sed -n '/axis figures/,$p'
say "ISO 230-4 of the ballbar circles above ($BALLBAR): G, F, H per circle and direction, and the ballbar's list"
"$BIN/fiveaxis" iso230-4 "$BALLBAR" --feed 1000 --plot "$IDIR"
# --- end section: iso230

# --- section: scale (issue 12)
BIG="$OUT/li2018_200k.parquet"
say "A continuous measurement of 200,000 poses ($BIG, Parquet) with a hidden roll of X: diagnose in row blocks"
"$BIN/fiveaxis" simulate --machine li2018 --n 200000 --effect ex_x:x1=1e-5 --with-sigma --seed 5 -o "$BIG" --force
"$BIN/fiveaxis" diagnose "$BIG" --top 3
# --- end section: scale

# --- section: compensation (issue 10)
# From the identified model to the controller, and the error falls on the (simulated) machine: an A/C trunnion with
# hidden errors and two effects is measured, fitted, compensated (volumetric table + LinuxCNC files), and measured
# again with the table applied to its commands (same seed: the same machine, poses and noise).
CDIR=out/compensation
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

# --- section: heat (issue 31)
# Heat from temperature sensors: which sensor drives which error, the calibration loop on a thermal test, the fitted
# model in the LinuxCNC kinematics module (a HAL input pin per sensor) and its predicted error at a warm state.
HDIR=out/heat
mkdir -p "$HDIR"
HEAT="$HDIR/li2018_heat.csv"
say "A 4-hour test on li2018 with four temperature sensors (spindle running 2 h, then stopped): the tool length grows 1.5 um/degC with temp_spindle through a 600 s lag, the X scale 11.5 um/m/degC with temp_xscale; temp_air and temp_motor drive nothing"
"$BIN/fiveaxis" simulate --machine li2018 --n 1500 --duration 14400 --seed 3 \
    --temperature spindle=spindle:rise=15,tau=900,off=7200 --temperature xscale=bed:rise=3,tau=5000 \
    --temperature air=air:amp=1 --temperature motor=mix:spindle=0.4,air=1 \
    --effect L:temp_spindle~600=0.0015 --effect dx_x:x.temp_xscale=0.0287 -o "$HEAT" --force
say "The calibration loop: fiveaxis diagnose $HEAT --machine li2018 --rounds 4 --top 3 (run once: the text below and the effects it found come from its JSON record)"
"$BIN/fiveaxis" diagnose "$HEAT" --machine li2018 --rounds 4 --top 3 --json > "$HDIR/rounds.json"
"$BIN/python" -c 'import json, sys; from fiveaxis.report import text
print(text.rounds(json.load(open(sys.argv[1]))["rounds"]))' "$HDIR/rounds.json"
FOUND=$("$BIN/python" -c 'import json, sys
print(" ".join("--add " + i for i in json.load(open(sys.argv[1]))["rounds"][-1]["added"]))' "$HDIR/rounds.json")
say "Fit what the loop found ($FOUND) and compensate at a warm state (temp_spindle 35 degC, temp_xscale its warmest reading)"
"$BIN/fiveaxis" fit "$HEAT" --machine li2018 $FOUND -o "$HDIR/model.json" --force | sed -n '/residual RMS/p;/temp_/p'
"$BIN/fiveaxis" compensate "$HDIR/model.json" -o "$HDIR/comp" --temperature spindle=35 --force | sed -n '/^  at /,/only the kinematics/p'
say "How the kinematics module reads the sensors (linuxcnc/volumetric/fiveaxis.hal)"
grep -E "temperature sensors|connected|thermal correction|temp-fault|net temp_|\.temp\.|\.channel |\.lag " "$HDIR/comp/linuxcnc/volumetric/fiveaxis.hal"
# --- end section: heat

# --- section: report (issue 11)
# The calibration report: one self-contained HTML page (and a PDF printed by headless Chromium) per data set.
OUT=out/report
PDF=(--pdf)
command -v chromium >/dev/null 2>&1 || { PDF=(); echo "(no chromium: HTML reports only; see make system-deps)"; }
say "ISO 230 names of the trunnion machine's errors: fiveaxis names --machine ac_trunnion"
"$BIN/fiveaxis" names --machine ac_trunnion | head -8
say "Calibration report of the example measurements: fiveaxis report $MEAS -o $OUT/li2018_example.html ${PDF[*]}"
"$BIN/fiveaxis" report "$MEAS" -o "$OUT/li2018_example.html" "${PDF[@]}" --force
say "Calibration report of the R-test on the A/C trunnion (above: $RTEST)"
"$BIN/fiveaxis" report "$RTEST" --machine ac_trunnion -o "$OUT/ac_trunnion_rtest.html" "${PDF[@]}" --force
say "Calibration report of the compensated A/C trunnion, with the compensation's predicted error maps"
"$BIN/fiveaxis" report "$CDIR/before.csv" --machine ac_trunnion --compensation "$CDIR/comp" \
    -o "$OUT/ac_trunnion_compensated.html" "${PDF[@]}" --force
say "Calibration certificate of the ISO 230-2 laser run above ($LASER) with a campaign file: HTML, PDF and DCC XML"
"$BIN/fiveaxis" report "$LASER" --machine ac_trunnion --campaign examples/campaign.toml --rounds 2 \
    -o "$OUT/ac_trunnion_laser_certificate.html" "${PDF[@]}" --dcc --force
say "Reports written (open in a browser):"
scripts/list-outputs.sh "$OUT"
# --- end section: report
