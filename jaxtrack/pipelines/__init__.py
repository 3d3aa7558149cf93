"""Host-side orchestration: running trackers over sequences, learning context, tuning, sweeps."""
