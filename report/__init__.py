"""The HTML report: renders what rsmcheck.orchestration.collect stored (docs/commands.md, "The report")."""
