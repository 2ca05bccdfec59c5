"""The board: ports by URL and what runs on it.

``link`` (open a port by URL, timestamped reads, every byte into a capture), ``flash`` (build the
firmware hex, flash it with avrdude through the bootloader, check its HELLO).
"""
