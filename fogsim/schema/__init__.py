"""One schema layer for every document fogsim reads (pydantic v2): the mechanism in
:mod:`fogsim.schema.base`, one module per family of documents. See ``docs/safety.md`` (Schemas)
for which model guards which file."""
