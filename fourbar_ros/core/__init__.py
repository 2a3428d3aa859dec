"""The pure math, numpy and the standard library only: kinematics, statics, synthesis, calibration."""
