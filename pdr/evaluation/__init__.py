"""Evaluations against ground truth: scorers and dataset protocols. Product code never imports this package."""
