"""Motion of the driven joint, numpy and ruckig without ROS: conversion, interpolation bound, limits, planning."""
