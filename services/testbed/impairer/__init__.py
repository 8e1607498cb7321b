"""A user-space link impairer: delay, jitter, loss and outages between two interfaces.

Where the kernel has no netem (``tc qdisc add ... netem`` fails), the test bed runs this
process inside its wire namespace, between the two veths of a link
(``python -m services.testbed.impairer --end air=radio-air --end ground=radio-ground
--control PATH --seed 0``). :mod:`.channel` is the seeded model of one direction on injected
times, :mod:`.forward` the ``AF_PACKET`` data path, :mod:`.control` the JSON control socket
through which a test changes the impairment or starts an outage while it runs.
"""
