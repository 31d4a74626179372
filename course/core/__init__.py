"""The core: errors, the implementation loader, traces, the optional-peer guard, data folders."""
