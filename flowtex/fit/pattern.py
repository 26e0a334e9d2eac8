def register_fit(kinds): pass
