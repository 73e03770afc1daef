"""ropecam's device side: frame capture, the per-frame measurement pipeline and the senders of the rig daemon."""
