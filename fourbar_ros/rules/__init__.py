"""What fourbar_node does with commands, written once and array-first (numpy takes one command or a block): the
accept/clamp/reject policy (policy.py), the velocity rule (velocity.py), and the outputs a served command publishes
(outputs.py: pose, coupler joint, effort layout, load). No ROS: the node calls these per command, ``fourbar
process`` per block, and ``fourbar compare`` and ``fourbar demo`` take their rules from here.
"""
