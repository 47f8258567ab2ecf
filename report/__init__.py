"""The HTML report: renders what rsmcheck.orchestration.collect stored (README, "The report")."""
