bulletnav evaluate --model runs/ppo_mission_g0/model.zip --env bulletnav/WarehouseMission-v0 --episodes 200 --seed 1000 --json
