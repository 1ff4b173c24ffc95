bulletnav evaluate --model models/ppo_dynamic.zip --env bulletnav/WarehouseDynamic-v0 --episodes 200 --seed 1000 --perturb laggy --json
