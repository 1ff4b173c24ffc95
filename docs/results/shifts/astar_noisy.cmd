bulletnav navigate --planner astar --episodes 50 --seed 1000 --perturb noisy --json
