"""The node graph and its launch, one process per node: model, parameters, supervisor, child, cli.

Nothing is imported here: the launch file needs `model` and `parameters` only.
"""
