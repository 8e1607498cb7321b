"""System 1 (Sec. III-A): Alg. 1 (RRT on OMPL) tracked by LQR."""
