"""The reader's bounds on a program that does not end (a module of its own, so a scenario's
schema names the default without importing the reader)."""

MAX_CALLS = 2_000_000
"""canonical calls a program may make before the reader refuses it as running on (a loop that
does not end, or more than the machine's memory holds read whole: about 0.3 kB a call read, more
once converted)"""
