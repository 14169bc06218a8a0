#!/bin/bash
# Usage: scripts/compare-plan.sh WORKTREE OUTDIR -- every instrument's plan (text, JSON, CSV, NGC) and simulate on
# every shipped machine, plan --check of every written program and of the bundled example; the outputs in OUTDIR,
# to compare two versions with diff -r (WORKTREE: a tree with .venv/bin/fiveaxis; paths in the texts made WT).
# Issue 30's instrument records: 294 files byte-identical before (7a2df38) and after (1fff6f3).
set -u
WT=$(cd "$1" && pwd); OUT=$2; mkdir -p "$OUT"; cd "$OUT"
FA="nice $WT/.venv/bin/fiveaxis"
run() { local name=$1; shift; "$@" > "$name.out" 2> "$name.err"; echo "rc=$?" >> "$name.out"; }
for m in li2018 ac_trunnion tilting_head; do
  for spec in "tip 20" "rtest 30" "probe-sphere 12" "ballbar 96" "interferometer 30 --effects dx_x:x1" "tracker 40"; do
    set -- $spec; i=$1; n=$2; shift 2
    b=plan_${m}_${i}
    run $b $FA plan --machine $m --instrument $i --n $n --seed 0 "$@" -o $b.csv
    run ${b}_json $FA plan --machine $m --instrument $i --n $n --seed 0 "$@" -o ${b}_j.csv --json
    [ -f $b.ngc ] && run check_${m}_${i} $FA plan --check $b.ngc --machine $m --poses $b.csv
  done
  run plan_${m}_rtest_L2 $FA plan --machine $m --instrument rtest --n 40 --seed 1 --tool-lengths 150,250 -o plan_${m}_rtest_L2.csv
  run plan_${m}_tip_eff $FA plan --machine $m --instrument tip --n 20 --tool-lengths 200,300 --effects ex_x:x2 -o plan_${m}_tip_eff.csv
  for i in tip rtest probe-sphere ballbar interferometer tracker test-part; do
    run sim_${m}_${i} $FA simulate --machine $m --instrument $i --n 120 --seed 3 -o sim_${m}_${i}.csv
  done
done
run plan_ac_joint_rtest $FA plan --machine ac_trunnion --instrument rtest --n 30 --kinematics joint -o plan_ac_joint_rtest.csv
run plan_ac_joint_ballbar $FA plan --machine ac_trunnion --instrument ballbar --n 48 --kinematics joint -o plan_ac_joint_ballbar.csv
run check_example $FA plan --check $WT/examples/ac_trunnion_sphere.ngc --machine ac_trunnion --instrument tip --kinematics tcp
run plan_doc_L2 $FA plan --machine ac_trunnion --instrument rtest --n 30 --tool-lengths 100,200 -o plan_doc_L2.csv
sed -i "s#$WT#WT#g" *.out *.err
