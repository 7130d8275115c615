"""Hydrodynamics: the generalised resistance of head + flagellum (``hydrodynamics``) from Lighthill's slender-body
theory (``lsbt``) and the Higdon head (``higdon_head``), or local resistive-force theory (``rft``), the O(N)
alternative."""
