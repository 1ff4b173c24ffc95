"""Simulation core: client, world, robot, layouts and start/goal sampling."""
