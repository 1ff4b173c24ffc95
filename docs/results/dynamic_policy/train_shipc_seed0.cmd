cp -r runs/dyn_curriculum_s0 runs/dyn_shipc_s0   # the 'curriculum' arm's seed 0 at 600k steps (in its last stage)
bulletnav train --algo ppo --env bulletnav/WarehouseDynamic-v0 --hyperparams bulletnav/rl/hyperparams/ppo_dynamic_curriculum.yml --timesteps 1000000 --seed 0 --out runs/dyn_shipc_s0 --eval-freq 50000 --eval-episodes 20 --no-progress --resume
# trained on from 600k to 1.0M steps with the same settings
