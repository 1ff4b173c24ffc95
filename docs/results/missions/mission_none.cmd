bulletnav navigate --env bulletnav/WarehouseMission-v0 --planner none --episodes 200 --seed 1000 --json
