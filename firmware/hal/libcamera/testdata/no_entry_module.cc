// A shared library without the camera module's entry point: the loader must refuse it.
extern "C" __attribute__((visibility("default"))) int mirrorscan_some_other_module() { return 0; }
