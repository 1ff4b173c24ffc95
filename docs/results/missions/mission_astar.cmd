bulletnav navigate --env bulletnav/WarehouseMission-v0 --planner astar --episodes 200 --seed 1000 --json
