"""sdbc_sim: a batched pymunk simulator of robot teams and the paper's three tasks."""
