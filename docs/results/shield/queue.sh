cd /work/main; source .venv/bin/activate
R=docs/results/shield
run() { # name, command...
  local name=$1; shift
  [ -s $R/$name.json ] && return
  echo "$*" > $R/$name.cmd
  nice -n 5 "$@" > $R/$name.json.tmp 2>>/tmp/sh/queue_shield.err && mv $R/$name.json.tmp $R/$name.json
}
M=models/ppo_warehouse.zip
run ppo_shield_31 bulletnav evaluate --model $M --episodes 200 --seed 1000000 --shield --json
run astar_shield_31 bulletnav navigate --planner astar --episodes 200 --seed 1000000 --shield --json
run ppo_shield_40 bulletnav evaluate --model $M --episodes 200 --seed 1000000 --obstacles 40 --shield --json
run astar_shield_40 bulletnav navigate --planner astar --episodes 200 --seed 1000000 --obstacles 40 --shield --json
run ppo_shield_hall bulletnav evaluate --model $M --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --shield --json
run astar_hall bulletnav navigate --planner astar --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --json
run astar_shield_hall bulletnav navigate --planner astar --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --shield --json
run ppo_shield_aisles bulletnav evaluate --env bulletnav/WarehouseAisles-v0 --model $M --episodes 200 --seed 1000 --shield --json
run astar_shield_aisles bulletnav navigate --env bulletnav/WarehouseAisles-v0 --planner astar --episodes 200 --seed 1000 --shield --json
run ppo_shield_dynamic bulletnav evaluate --env bulletnav/WarehouseDynamic-v0 --model $M --episodes 200 --seed 1000 --shield --json
run astar_shield_dynamic bulletnav navigate --env bulletnav/WarehouseDynamic-v0 --planner astar --episodes 200 --seed 1000 --shield --json
