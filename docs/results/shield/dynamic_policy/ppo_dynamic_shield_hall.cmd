bulletnav evaluate --model models/ppo_dynamic.zip --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --shield --json
