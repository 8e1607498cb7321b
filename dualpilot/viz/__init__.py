"""Figures: the paper's per-mission panels (Fig. r1-r3) and Fig. r5."""
