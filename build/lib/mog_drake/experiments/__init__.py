"""The paper's experiments as functions returning tables."""
