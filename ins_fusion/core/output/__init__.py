"""The engine's output: the solution, its rows and the numbers the messages carry."""
