bulletnav train --algo ppo --env bulletnav/WarehouseDynamic-v0 --timesteps 600000 --seed 1 --out runs/dyn_none_s1 --eval-freq 50000 --eval-episodes 20 --no-progress
# ablation arm 'none' (no curriculum, no randomization); resumed after interruptions with the same command plus --resume
