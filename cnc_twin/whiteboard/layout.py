"""Memory map of the whiteboard, in 16-bit word addresses, for a RAM of ``words`` words.

The RAM splits in two halves, each written by one side only; the last two words are the
mailboxes (writing one interrupts the other side on the real card). Every word has exactly one
writer, and every multi-word block is published by a word written after it (an index or a
mailbox), so a reader never acts on a half-written block. 32-bit fields sit at even word
addresses and 64-bit fields at multiples of 4 words, so each is one aligned store.

Default map (8K x 16 bit = 16 KiB):

==================  =====  ====================================================================
address (words)     owner  contents
==================  =====  ====================================================================
0x0000 - 0x001F     PC     PC control block: magic, version, PC state, heartbeat, FIFO write
                           index, HOLD, planned program length, counters (``PC_*`` below)
0x0020 - 0x0FFF     PC     command FIFO: ring of typed records (4064 words)
0x1000 - 0x101F     DSP    DSP control block: HOLDA, FIFO read index, DSP heartbeat (``DSP_*``)
0x1020 - 0x10FF     DSP    status block (:mod:`~cnc_twin.whiteboard.status`)
0x1100 - 0x1FFD     -      reserved
0x1FFE              PC     mailbox PC -> DSP: low 16 bits of the period whose status was answered
0x1FFF              DSP    mailbox DSP -> PC: low 16 bits of the period whose status was posted
==================  =====  ====================================================================

For another size (a power of two >= 2048 words) the halves and the FIFO scale; the control
blocks, the status block and the mailboxes keep their places relative to each half and the top.
"""

from __future__ import annotations

from dataclasses import dataclass

MAGIC = 0x54434E43  # "CNCT" little-endian, written by the PC when it has attached
VERSION = 1
DEFAULT_WORDS = 8192
CONTROL_WORDS = 32
STATUS_WORDS = 224

# PC control block, word offsets from 0.
PC_MAGIC = 0          # u32
PC_VERSION = 2        # u16
PC_STATE = 3          # u16, PcState
PC_HEARTBEAT = 4      # u32, incremented while the planner is alive and not stalled
PC_FIFO_WRITE = 6     # u32, words written to the FIFO so far (mod 2^32); written after the data
PC_HOLD = 8           # u16, 1 while the PC is using the bus
PC_PROGRAM_PERIODS = 10  # u32, planned duration of the whole program [interpolation periods]
PC_RECORDS_SENT = 12  # u32
PC_RETRANSMITS = 14   # u32, records sent again after the DSP rejected one
PC_ACK_TIME = 16      # u64, monotonic clock [ns] when the PC acknowledged the last status
PC_PLAN_US = 20       # u32, wall-clock time the planner spent planning the program [us]
PC_PLAN_BLOCKS = 22   # u32, motion blocks (moves, curve blocks) it planned
PC_ALL_SENT = 24      # u16, 1 when the whole program is in the FIFO and no fault is scheduled:
                      # the card may stop exchanging (it resumes to ask for a resend)
PC_WAKE_FREE = 25     # u16, 0, or the free FIFO words the PC's next record needs: the card need
                      # not exchange until its FIFO has that much room (its FIFO-threshold interrupt)

# DSP control block, word offsets from the DSP half's base.
DSP_HOLDA = 0         # u16, 1 while the bus is granted to the PC
DSP_FIFO_READ = 2     # u32, words consumed from the FIFO so far (mod 2^32)
DSP_HEARTBEAT = 4     # u32, the DSP's period counter
DSP_SHUTDOWN = 6      # u16, 1 when the run is over: the planner exits
DSP_END_STATE = 7     # u16, the controller state the run ended in (DspState), written before SHUTDOWN
DSP_END_FAULT = 8     # u16, the fault code it ended with (FaultCode, 0 none), written before SHUTDOWN


class PcState:
    """Values of the PC_STATE word."""

    NONE = 0
    READY = 1      # attached, program planned, waiting for the first status
    STREAMING = 2
    DONE = 3       # saw the DSP finish; exiting
    ERROR = 4      # the planner failed; see its stderr


@dataclass(frozen=True)
class Layout:
    """Addresses for a RAM of ``words`` 16-bit words. All values are word addresses or counts."""

    words: int = DEFAULT_WORDS

    def __post_init__(self) -> None:
        if self.words < 2048 or self.words & (self.words - 1):
            raise ValueError(f"whiteboard size must be a power of two >= 2048 words, got {self.words}")

    @property
    def nbytes(self) -> int:
        return 2 * self.words

    @property
    def pc_control(self) -> int:
        return 0

    @property
    def fifo_base(self) -> int:
        return CONTROL_WORDS

    @property
    def fifo_words(self) -> int:
        return self.words // 2 - CONTROL_WORDS

    @property
    def dsp_control(self) -> int:
        return self.words // 2

    @property
    def status_base(self) -> int:
        return self.words // 2 + CONTROL_WORDS

    @property
    def mailbox_to_dsp(self) -> int:
        """Written by the PC (interrupts the DSP)."""
        return self.words - 2

    @property
    def mailbox_to_pc(self) -> int:
        """Written by the DSP (interrupts the PC)."""
        return self.words - 1

    def memory_map(self) -> list[tuple[str, str, str]]:
        """Rows ``(address range, owner, contents)`` for documentation."""

        def rng(a: int, b: int) -> str:
            return f"0x{a:04X} - 0x{b:04X}" if b > a else f"0x{a:04X}"

        reserved_start = self.status_base + STATUS_WORDS
        return [
            (rng(0, CONTROL_WORDS - 1), "PC", "PC control block"),
            (rng(self.fifo_base, self.fifo_base + self.fifo_words - 1), "PC", f"command FIFO ({self.fifo_words} words)"),
            (rng(self.dsp_control, self.dsp_control + CONTROL_WORDS - 1), "DSP", "DSP control block"),
            (rng(self.status_base, reserved_start - 1), "DSP", "status block"),
            (rng(reserved_start, self.words - 3), "-", "reserved"),
            (rng(self.mailbox_to_dsp, self.mailbox_to_dsp), "PC", "mailbox PC -> DSP"),
            (rng(self.mailbox_to_pc, self.mailbox_to_pc), "DSP", "mailbox DSP -> PC"),
        ]
