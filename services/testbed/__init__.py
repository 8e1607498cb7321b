"""The deployment test bed: the air, ground and gcs hosts on one machine, the links between
them shaped like a radio.

``python -m services.testbed`` (``make testbed``) brings it up, prints the hosts and waits;
tests use :class:`TestBed` (``with TestBed() as bed: ...``). By job: :mod:`.topology` (hosts,
links, addresses, names), :mod:`.netns` (``ip`` and sockets inside namespaces),
:mod:`.shaping` (``tc``: tbf and netem), :mod:`.links` (a link's shaping at run time),
:mod:`.impairer` (the user-space impairer, where the kernel has no netem), :mod:`.bed` (up
and down as one), :mod:`.leftovers` (removal, also after a crash), :mod:`.availability`
(whether namespaces can be made here), :mod:`.measure` (ping, UDP and TCP flows between hosts),
:mod:`.mission` and :mod:`.fleet` (missions across the hosts: one, or a fleet whose vehicles
each have their own link), :mod:`.grid` (the cells of the link varied one factor at a time).
See docs/testbed.md.

Import what you use from its module (``from services.testbed.bed import TestBed``): this
package's own import stays light, since the impairer's process starts from it.
"""
