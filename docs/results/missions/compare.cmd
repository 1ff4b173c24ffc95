bulletnav compare runs/ppo_mission_g0 runs/ppo_mission_g1 --out docs/mission_learning_curves.png
