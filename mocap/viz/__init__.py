"""Static figures (PNG) for people: contact sheets, plots. Recording lives in mocap.recording."""
