"""The fast solver of (P2): fixed faces, a convex QP, a small interior point."""
