"""The reader's bounds on a program that does not end (a module of its own, so a scenario's
schema names the default without importing the reader)."""

MAX_CALLS = 2_000_000
"""canonical calls a program may make while a loop (``while``, ``do``, ``repeat``) is open before
the reader refuses it as running on: a loop that does not end, caught before the calls it made
fill the memory (about 0.3 kB a call read); lines written out, however many, end with the file"""
