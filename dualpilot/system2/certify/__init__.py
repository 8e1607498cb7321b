"""System 2 with a certificate: a valid lower bound on Problem (P2) and the exact method."""
