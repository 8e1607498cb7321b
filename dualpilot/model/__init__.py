"""The models of Sec. II: UAV dynamics (Eq. 1), the fire process (Sec. II-B), polytopes."""
