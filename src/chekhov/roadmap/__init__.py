"""The Chekhov roadmap: offline PRM over the static obstacles with cached shortest paths."""
