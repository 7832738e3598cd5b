"""Module types of umbra, grouped by domain; the pure math lives beside each module."""
