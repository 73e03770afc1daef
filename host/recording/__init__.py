"""MCAP recording: the writer (flushes, rolling, failures), Foxglove schemas and converters, crash recovery."""
