"""The Rauch-Tung-Striebel smoother: its backward pass and the history of a forward run."""
