"""The HTML report: renders what rsmcheck.collect stored (README, "The report")."""
