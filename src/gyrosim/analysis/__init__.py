"""Analyses of classical mechanics on any scene: small oscillations (linear) and chaos."""
