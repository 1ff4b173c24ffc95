bulletnav train --algo ppo --env bulletnav/WarehouseDynamic-v0 --hyperparams bulletnav/rl/hyperparams/ppo_dynamic_both.yml --timesteps 600000 --seed 0 --out runs/dyn_both_s0 --eval-freq 50000 --eval-episodes 20 --no-progress
# ablation arm 'both'; resumed after interruptions with the same command plus --resume
