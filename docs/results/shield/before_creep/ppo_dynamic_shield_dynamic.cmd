bulletnav evaluate --env bulletnav/WarehouseDynamic-v0 --model models/ppo_dynamic.zip --episodes 200 --seed 1000 --shield --json
