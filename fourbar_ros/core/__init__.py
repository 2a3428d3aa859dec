"""The pure math: geometry, kinematics, statics, synthesis. numpy and the standard library only."""
