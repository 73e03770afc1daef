"""The rig daemon: capture, measure, stream, obey authenticated control, report health, survive faults."""
