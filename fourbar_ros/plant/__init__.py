"""The linkage on the pole as a MuJoCo plant: its model generated from the configuration, and a simulation of it."""
