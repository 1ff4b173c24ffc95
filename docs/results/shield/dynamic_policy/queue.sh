source .venv/bin/activate; R=docs/results/shield/dynamic_policy; mkdir -p $R
run() { local name=$1; shift; [ -s $R/$name.json ] && return; echo "$*" > $R/$name.cmd; nice -n 5 "$@" > $R/$name.json.tmp 2>>$R/queue.err && mv $R/$name.json.tmp $R/$name.json; }
M=models/ppo_dynamic.zip
run ppo_dynamic_31 bulletnav evaluate --model $M --episodes 200 --seed 1000000 --json
run ppo_dynamic_shield_31 bulletnav evaluate --model $M --episodes 200 --seed 1000000 --shield --json
run ppo_dynamic_40 bulletnav evaluate --model $M --episodes 200 --seed 1000000 --obstacles 40 --json
run ppo_dynamic_shield_40 bulletnav evaluate --model $M --episodes 200 --seed 1000000 --obstacles 40 --shield --json
run ppo_dynamic_hall bulletnav evaluate --model $M --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --json
run ppo_dynamic_shield_hall bulletnav evaluate --model $M --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --shield --json
run ppo_dynamic_aisles bulletnav evaluate --env bulletnav/WarehouseAisles-v0 --model $M --episodes 200 --seed 1000 --json
run ppo_dynamic_shield_aisles bulletnav evaluate --env bulletnav/WarehouseAisles-v0 --model $M --episodes 200 --seed 1000 --shield --json
