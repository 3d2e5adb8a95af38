def main():
    """Run."""
    pass
