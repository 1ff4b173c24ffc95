cd /work/main; source .venv/bin/activate
# wait for the screening run
while pgrep -f "/tmp/scr/run.sh" >/dev/null; do sleep 30; done
for arm in $ARMS; do for s in 0 1; do for p in none slippery heavy noisy miscalibrated laggy; do
  out=docs/results/curriculum/ablation/${arm}_seed${s}_${p}.json
  [ -s $out ] && continue
  extra=""; [ $p != none ] && extra="--perturb $p"
  nice -n 5 bulletnav evaluate --model runs/dyn_${arm}_s$s/model.zip --env bulletnav/WarehouseDynamic-v0 --episodes 50 --seed 1000 $extra --json > $out.tmp 2>/tmp/scr/abl.err && mv $out.tmp $out
done; done; done
