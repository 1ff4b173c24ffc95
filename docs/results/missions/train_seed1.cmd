bulletnav train --algo ppo --env bulletnav/WarehouseMission-v0 --timesteps 400000 --seed 1 --out runs/ppo_mission_g1 --eval-freq 50000 --eval-episodes 20 --no-progress
# resumed after an interruption with the same command plus --resume
