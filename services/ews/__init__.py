"""The EWS service: owns the fire process (``python -m services.ews``)."""
