"""The spec language: its schema (pydantic), its units, its YAML source positions and its loader."""
