bulletnav evaluate --env bulletnav/WarehouseAisles-v0 --model models/ppo_warehouse.zip --episodes 200 --seed 1000 --shield --json
