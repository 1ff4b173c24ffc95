bulletnav evaluate --model models/ppo_warehouse.zip --episodes 50 --seed 1000 --perturb slippery --json
