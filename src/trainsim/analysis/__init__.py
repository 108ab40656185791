"""trainsim.analysis."""
