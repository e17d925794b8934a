"""The PC side: turns a scenario's program into segments the card executes."""
