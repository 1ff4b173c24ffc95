bulletnav evaluate --env bulletnav/WarehouseAisles-v0 --model models/ppo_warehouse.zip --episodes 60 --seed 7000 --shield --json
