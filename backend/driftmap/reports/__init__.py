"""Evaluation reports: tables and PNG figures against ground truth, like the papers'."""
