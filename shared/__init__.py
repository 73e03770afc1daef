"""Types, errors, units, configuration helpers and the wire protocol shared by the device and the host."""
