"""Pictures and (later) the interactive viewer."""
