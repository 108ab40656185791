"""trainsim.sim."""
