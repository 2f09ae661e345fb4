"""Support shared by the tests and the benchmarks (not used by the package itself): the fuzz corpus (it needs
hypothesis, a test dependency) and the shipped JSON Schemas' validators (jsonschema)."""
