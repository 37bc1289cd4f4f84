"""Schemas and durable storage for study data (session store, protocol schema)."""
