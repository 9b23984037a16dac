"""Primitives both packages share (rotations, signing keys, free UDP ports); imports neither gcs_swarm nor
sitl_sim (docs/architecture.md)."""
