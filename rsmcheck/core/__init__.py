"""The foundation every other layer reads: parameters, geometry, beams, orbit, errors,
observables, the case model and loader, run files, the engine protocol and the plug-in
registry.  It imports no engine, no driver and no orchestration."""
