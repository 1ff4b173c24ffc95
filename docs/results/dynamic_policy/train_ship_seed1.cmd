cp -r runs/dyn_none_s1 runs/dyn_ship_s1   # the 'none' arm's seed 1 at 600k steps
bulletnav train --algo ppo --env bulletnav/WarehouseDynamic-v0 --timesteps 1000000 --seed 1 --out runs/dyn_ship_s1 --eval-freq 50000 --eval-episodes 20 --no-progress --resume
# trained on from 600k to 1.0M steps with the same settings (ppo.yml's WarehouseDynamic-v0 entry)
