bulletnav navigate --planner astar --episodes 200 --seed 1000000 --obstacles 40 --shield --json
