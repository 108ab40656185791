"""trainsim.io."""
