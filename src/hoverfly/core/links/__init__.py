"""The configuration links: the links task and the CLI, MSP and seed-001 maintenance servers."""
