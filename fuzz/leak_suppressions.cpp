// Leaks that are not scalemesh's, so that libFuzzer's leak check stops only on
// ours: ITK 5.2's NRRD and MetaImage readers leak their parse structures when
// they refuse a file (itk_nrrdNew, itk_biffGet, MetaImage::ReadStream),
// OpenVDB leaks the nodes it read when a corrupt tree makes readTopology
// throw, and the Gmsh SDK keeps allocations until the process ends.
extern "C" const char* __lsan_default_suppressions()
{
    return "leak:libITKNrrdIO\nleak:libITKMetaIO\nleak:readTopology\nleak:libgmsh\n";
}
