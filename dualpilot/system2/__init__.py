"""System 2 (Sec. III-B): Problem (P2), its exact MIQP and the fast solver."""
