"""stealth-nav behind Nav2's own interfaces (planner server, navigator, exposure mask)."""
