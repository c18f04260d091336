"""placeholder"""
def main():
    print("cli")
