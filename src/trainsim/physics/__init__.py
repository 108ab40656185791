"""trainsim.physics."""
