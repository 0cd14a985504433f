"""Writers: the end of the flow, turning a finished map or a log into files."""
