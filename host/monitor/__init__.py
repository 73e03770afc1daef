"""The live monitor: per-device statistics, the rich or plain display, and the `ropecam monitor` command."""
