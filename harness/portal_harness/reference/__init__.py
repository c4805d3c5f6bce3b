"""Each sweep point's reference: the pilots that choose its strategies, its
renders and their combination, the bias test, the noise check and extensions.

May import core/, experiment/ and execution/."""
