"""The simulated vehicle: a MAVLink endpoint flying Eq. (1) (``python -m services.uavsim``)."""
