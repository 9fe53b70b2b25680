"""Pictures: factor-graph drawings and annotated frames."""
