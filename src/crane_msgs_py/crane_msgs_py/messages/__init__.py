"""Messages and their conventions: names of nodes, topics and joints, conversions between messages and arrays,
the reference's CDR bytes."""
