"""Distributed surveillance (seed 004): one tracker per radar, local tracks fused into system tracks."""
