bulletnav navigate --env bulletnav/WarehouseDynamic-v0 --planner rrt --episodes 200 --seed 1000 --json
