"""Built-in node types. Each module is registered through the ``flowtex.nodes`` entry point group."""
