bulletnav evaluate --model models/ppo_dynamic.zip --episodes 200 --seed 1000000 --json
