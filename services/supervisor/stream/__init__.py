"""The setpoint stream in a process of its own, so nothing the supervisor does can starve it.

The 20 Hz SET_POSITION_TARGET_LOCAL_NED and 1 Hz HEARTBEAT of every vehicle
link are sent by a small child process (``__main__.py``) with real-time or
raised priority, not by a thread beside the supervisor's computing: that
thread needs the GIL, and under load the thread holding it may itself be off
the CPU. The supervisor hands it the link's socket and each new setpoint
(``client.py``; the messages are in ``protocol.py``).
"""
