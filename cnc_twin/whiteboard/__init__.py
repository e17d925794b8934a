"""The whiteboard: an emulated dual-port RAM shared by the PC planner and the DSP card.

A ``multiprocessing.shared_memory`` block of 16-bit words laid out like the card's dual-port RAM
(see :mod:`~cnc_twin.whiteboard.layout` for the memory map). Modules:

- :mod:`~cnc_twin.whiteboard.layout`   addresses, owners, the memory-map table
- :mod:`~cnc_twin.whiteboard.records`  the typed command records the PC sends the card
- :mod:`~cnc_twin.whiteboard.codec`    their wire format: header, payload, CRC-16; encode/decode
- :mod:`~cnc_twin.whiteboard.fifo`     the command ring FIFO (PC writes, DSP reads)
- :mod:`~cnc_twin.whiteboard.status`   the DSP status block
- :mod:`~cnc_twin.whiteboard.block`    creating, attaching and always unlinking the segment
- :mod:`~cnc_twin.whiteboard.ports`    the exchange protocol, one class per side
- :mod:`~cnc_twin.whiteboard.doorbell` the mailbox interrupts: pipes a waiter sleeps on

May import: core, motion. Imported by: dsp, planner (both sides of the exchange), view, scenario, run, studies.
"""
