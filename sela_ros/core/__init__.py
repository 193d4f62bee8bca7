"""The learning core: GP, acquisition, SELA, planning, archive, detection, mission and
persistence. numpy/scipy only, no ROS, nothing above it."""
