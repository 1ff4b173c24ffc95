bulletnav train --algo ppo --env bulletnav/WarehouseDynamic-v0 --hyperparams bulletnav/rl/hyperparams/ppo_dynamic_curriculum.yml --timesteps 600000 --seed 0 --out runs/dyn_curriculum_s0 --eval-freq 50000 --eval-episodes 20 --no-progress
# ablation arm 'curriculum'; resumed after interruptions with the same command plus --resume
