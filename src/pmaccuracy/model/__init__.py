"""What a robot is: leg chains and leg types, the manipulator, serial arms, error sources and clearance
sets, the TOML reading of robot and clearance files, and the plausibility checks of their values."""
