"""Frame and metadata writers and readers (DNG, EXR, JSON), all written atomically."""
