"""The learning core: GP, acquisition, SELA, planning, archive, detection, the mission
stepper, geometry and persistence. numpy/scipy only, no ROS, nothing above it."""

#: Parameters of one gait: the open-loop controller's (sim_bridge.controller), what an
#: archive stores per behaviour and what a behaviour command carries.
N_PARAMS = 36
