"""The force terms of the implicit step behind one interface and the scene that sums them (``force_terms``), the
frozen descriptions of the system and of the step they work from (``step_context``), and head-rod / rod-rod
penalty contact (``contact``). The elastic terms themselves are in ``physics.elastic``."""
