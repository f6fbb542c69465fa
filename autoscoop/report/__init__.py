"""Reports from episode records: tables, figures, video files. Nothing here runs the simulator."""
