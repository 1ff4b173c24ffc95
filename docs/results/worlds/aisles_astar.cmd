bulletnav navigate --env bulletnav/WarehouseAisles-v0 --planner astar --episodes 200 --seed 1000 --json
