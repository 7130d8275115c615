"""The swimmer's geometry and kinematics: the initial configuration and DOF layout (``geometry``), the rod's
reference and material frames (``frames``), the head's body frame (``body_frame``) and the best-fit rigid
rotation between two configurations (``rigid_alignment``)."""
