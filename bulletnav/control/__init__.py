"""Classical control: PID and the navigator."""
