"""The Rauch-Tung-Striebel smoother: its backward pass and the recorder of a forward run."""
