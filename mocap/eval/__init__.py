"""Evaluation against ground truth: joint errors (HumanEva), MMTA/MMTP (Canton-Ferrer)."""
