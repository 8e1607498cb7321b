"""The closed-loop mission of Sec. IV: one step over three ports, and its records."""
