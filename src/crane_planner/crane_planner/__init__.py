"""Anti-sway reference planning for a double-pendulum crane (Boscariol & Richiedei 2018)."""
