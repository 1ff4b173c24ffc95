bulletnav evaluate --model models/ppo_warehouse.zip --episodes 200 --seed 1000000 --shield --json
