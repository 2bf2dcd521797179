"""Board tools: deploy (tools.flash) and monitoring; see the README for what exists."""
