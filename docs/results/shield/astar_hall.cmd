bulletnav navigate --planner astar --episodes 100 --seed 0 --world bulletnav/assets/worlds/hall.yaml --json
