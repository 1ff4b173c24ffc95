bulletnav train --algo ppo --env bulletnav/WarehouseDynamic-v0 --timesteps 600000 --seed 0 --out runs/dyn_none_s0 --eval-freq 50000 --eval-episodes 20 --no-progress
# ablation arm 'none' (no curriculum, no randomization); resumed after interruptions with the same command plus --resume
