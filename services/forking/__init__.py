"""Services forked from a warm server instead of fresh interpreters (services/forking/server.py).

This package imports nothing heavy: the server's first import, :mod:`services.forking.threads`,
must run before numpy loads BLAS.
"""
