"""Reinforcement learning with Stable-Baselines3: training, evaluation, hyperparameters."""
