"""Everything that reads or writes PRISM: :mod:`.program` (stormpy's program API) and :mod:`.writer` (text)."""
