"""Switched full-duplex Ethernet/UDP, frame by frame, with the model netcfg.timing.ethernet analyses.

Every cable is two links, one per direction, each with its own FIFO transmitter at the bus bitrate. A frame of a
message with `size` data bytes carries the 1-byte application message id too (seed 001, Table 6.1), so it takes
udp_message_ns(size) on every link, padded to the 84-byte minimum (seed 001, eq. 6.4). Along its tree path the
frame is: released on its producer's drifting clock, handed to the NIC after the node's tx_delay (Tpre), queued
FIFO on the node's link, received completely by the switch (store and forward) after the cable's propagation time,
queued after the switch's latency (Tmux) on each egress port it leaves by (a multicast once per port), and
delivered to a consumer rx_delay (Tpost) after it has been received completely there. A receiving node may also
consume frames one after another (a FIFO server whose service time lies between a BCET and a WCET), which gives a
separate "processed" latency; flows and message-activated tasks see the delivery, as the analysis does.

The pieces, where a reader looks for them: links.py (a link, a receiving node's server, frame batches),
topology.py (the tree, each message's routes, sources and listeners: set up once), free.py (free-running links,
a chunk of simulated time at a time with numpy), events.py (chained frames and the links they cross, frame by
frame), results.py (what the run measured), network.py (EthernetNetwork: the one object a scenario builds).
"""

from netcfg.sim.ethernet.links import CHUNK_NS
from netcfg.sim.ethernet.network import EthernetNetwork
from netcfg.timing.ethernet import QUEUE_FRAMES

__all__ = ["CHUNK_NS", "QUEUE_FRAMES", "EthernetNetwork"]
