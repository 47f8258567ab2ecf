"""Orchestration: what drives the engines and judges their runs — the engine factory,
phase chaining, comparison, collection for the report, the gate, studies, the benchmark,
eigenfrequencies, closed-loop analysis, fault injection (README, Layout).  Above the floor,
the shared driver and the engines; below the report and the command line."""
